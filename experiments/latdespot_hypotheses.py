"""The thesis' ch. 7 hypotheses judged on a Lat-POMDP study's scenes (sec. 7.3.2, 7.3.4).

- H2, "Rel-SARSOP can outperform Lift-QMDP on Lat-POMDP", and H3, "Lift-QMDP can
  outperform Rel-SARSOP": each shown when one policy beats the other on some scene, where
  *beats* means their 95 % intervals are apart. The thesis judges them on Fig. 7.4, whose
  rows are the value on the discrete model and the success rate on the continuous one, so
  both measures are judged (``by_value``, ``by_success``).
- H4, "Lat-DESPOT is the only policy that performs near-optimally on all four scenes":
  as the project's acceptance reads it, Lat-DESPOT's success rate lies inside the best
  policy's interval, or is the best, on every scene (``near_best_everywhere``), and its
  interval lies above Lift-SARSOP's on ``cul_de_sac``, the thesis' trap for a myopic
  policy (``above_lift_sarsop_on_cul_de_sac``).
- ``feasible_only``: the policies that check the lattice (the Lift policies and the
  Lat-DESPOTs) never executed an infeasible action.

A hypothesis whose policies were not run is ``None``.
"""

from __future__ import annotations

CHECKS_LATTICE = ("lift-qmdp", "lift-sarsop", "lat-despot", "lat-despot-pb",
                  "lat-despot-continuous")
"""The policies that take only actions the lattice says are feasible."""
TRAP_SCENE = "cul_de_sac"


def _value_interval(entry: dict) -> tuple[float, float]:
    half = entry["discounted_value_ci95"]
    return entry["discounted_value"] - half, entry["discounted_value"] + half


def _success_interval(entry: dict) -> tuple[float, float]:
    return tuple(entry["success_rate_ci95"])


MEASURES = {"by_value": _value_interval, "by_success": _success_interval}


def beaten_on(scenes: dict, winner: str, loser: str) -> dict[str, list[str]] | None:
    """``{measure: [scene, ...]}``: the scenes where ``winner``'s 95 % interval lies above
    ``loser``'s, per measure (None: either policy missing from a scene)."""
    if not all(winner in e and loser in e for e in scenes.values()):
        return None
    return {measure: [scene for scene, e in scenes.items()
                      if interval(e[winner])[0] > interval(e[loser])[1]]
            for measure, interval in MEASURES.items()}


def near_best(entries: dict, policy: str) -> bool:
    """``policy``'s success rate is the highest or inside the highest's Wilson interval."""
    best = max(entries, key=lambda p: entries[p]["success_rate"])
    return entries[policy]["success_rate"] >= entries[best]["success_rate_ci95"][0]


def hypotheses(scenes: dict) -> dict:
    """H2, H3, H4 and ``feasible_only`` (see the module docstring) from part ``scenes``'s
    ``{scene: {policy: entry}}``."""
    h2 = beaten_on(scenes, "rel-sarsop", "lift-qmdp")
    h3 = beaten_on(scenes, "lift-qmdp", "rel-sarsop")
    out = {"H2": None if h2 is None else {
               "scenes": h2, "shown": {m: bool(s) for m, s in h2.items()}},
           "H3": None if h3 is None else {
               "scenes": h3, "shown": {m: bool(s) for m, s in h3.items()}}}
    h4 = None
    if all("lat-despot" in e for e in scenes.values()):
        near = {scene: near_best(e, "lat-despot") for scene, e in scenes.items()}
        trap = scenes.get(TRAP_SCENE, {})
        above = None
        if "lift-sarsop" in trap:
            above = bool(_success_interval(trap["lat-despot"])[0]
                         > _success_interval(trap["lift-sarsop"])[1])
        h4 = {"near_best": near, "near_best_everywhere": all(near.values()),
              "above_lift_sarsop_on_cul_de_sac": above,
              "shown": bool(all(near.values()) and above)}
    out["H4"] = h4
    checked = {scene: {p: e[p]["infeasible_rate"] for p in CHECKS_LATTICE if p in e}
               for scene, e in scenes.items()}
    out["feasible_only"] = {"infeasible_rate": checked, "holds": all(
        rate == 0.0 for rates in checked.values() for rate in rates.values())}
    return out
