"""``cmanip experiment latdespot``: runs part ``rel`` (:mod:`experiments.latdespot_study`),
``scenes`` and ``bound`` (:mod:`experiments.latdespot_scenes`), or ``all``, and writes
their summary and figures."""

from __future__ import annotations

import json
from pathlib import Path

from experiments.latdespot_hypotheses import hypotheses
from experiments.latdespot_plots import plot_bound, plot_rel, plot_scenes
from experiments.latdespot_scenes import (
    SceneSettings,
    Solved,
    bound_check,
    rel_upper_bounds,
    run_scenes,
    settings_dict,
)
from experiments.latdespot_study import RelSettings, build_rel_problem, evaluate_rel, solve_rel
from experiments.runner import Backend

SOLVED_FILE = "solved_rel.npz"
"""The point-based policy and corner bound of a study, in its directory: the workers of part
``scenes`` load them, and a resumed study reuses them rather than solving again."""


def run_study(part: str, settings: RelSettings, scenes: SceneSettings, out: Path, *,
              backend: Backend = Backend(), resume: bool = False,
              progress: bool = True) -> dict:
    """Part ``rel``, ``scenes``, ``bound`` or ``all`` (see the module docstrings of this
    module and :mod:`experiments.latdespot_scenes`): writes ``summary.json`` (``rel``,
    ``scenes`` with its ``hypotheses`` (:mod:`experiments.latdespot_hypotheses`),
    ``bound`` as run) and the PNGs. The scene episodes run on ``backend``
    (kept in ``out/trials.jsonl``; ``resume`` runs only the missing ones and reuses the
    solved policy in ``out``); part ``rel``'s online episodes on ``backend`` too (not
    kept). The results depend on neither."""
    out.mkdir(parents=True, exist_ok=True)
    model, belief, initial = build_rel_problem(settings)
    solved_path = out / SOLVED_FILE
    reuse = resume and solved_path.is_file()
    kept = Solved.load(solved_path) if reuse else None
    policies, costs, corner = solve_rel(settings, model, initial,
                                        sarsop=None if kept is None else kept.sarsop)
    if kept is not None:
        corner = kept.corner
    else:
        Solved(policies["rel-sarsop"], corner).save(solved_path)
    summary = {"part": part, "settings": settings_dict(settings, scenes),
               "model": {"states": len(model.pomdp.states),
                         "actions": list(model.pomdp.actions),
                         "observations": len(model.pomdp.observations), **costs,
                         "sarsop_reused_from": str(solved_path) if reuse else None}}
    if part in ("rel", "all"):
        summary["rel"] = evaluate_rel(settings, model, belief, initial, policies,
                                      backend=backend)
    if part in ("scenes", "bound", "all"):
        bound = part in ("bound", "all")
        summary["scenes"], on_rel = run_scenes(settings, scenes, solved_path, out,
                                               bound=bound, backend=backend, resume=resume,
                                               progress=progress)
        summary["hypotheses"] = hypotheses(summary["scenes"])
        if bound:
            upper = rel_upper_bounds(settings, scenes, model, belief, initial)
            summary["bound"] = bound_check(on_rel, summary["scenes"], upper)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if part in ("rel", "all"):
        plot_rel(summary, out)
    if "scenes" in summary:
        plot_scenes(summary, out)
    if "bound" in summary:
        plot_bound(summary, out)
    return summary
