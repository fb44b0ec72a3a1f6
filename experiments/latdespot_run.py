"""``cmanip experiment latdespot``: runs part ``rel`` (:mod:`experiments.latdespot_study`),
``scenes`` and ``bound`` (:mod:`experiments.latdespot_scenes`), or ``all``, and writes
their summary and figures."""

from __future__ import annotations

import json
from pathlib import Path

from experiments.latdespot_plots import plot_rel, plot_scenes
from experiments.latdespot_scenes import (
    SceneSettings,
    Solved,
    bound_check,
    run_scenes,
    settings_dict,
)
from experiments.latdespot_study import RelSettings, build_rel_problem, evaluate_rel, solve_rel


def run_study(part: str, settings: RelSettings, scenes: SceneSettings, out: Path, *,
              workers: int = 1) -> dict:
    """Part ``rel``, ``scenes``, ``bound`` or ``all`` (see the module docstrings of this
    module and :mod:`experiments.latdespot_scenes`): writes ``summary.json`` (``rel``,
    ``scenes``, ``bound`` as run) and the PNGs; ``workers`` processes run the episodes that
    plan online (the results do not depend on it)."""
    out.mkdir(parents=True, exist_ok=True)
    model, belief, initial = build_rel_problem(settings)
    policies, costs, corner = solve_rel(settings, model, initial)
    summary = {"part": part, "settings": settings_dict(settings, scenes),
               "model": {"states": len(model.pomdp.states),
                         "actions": list(model.pomdp.actions),
                         "observations": len(model.pomdp.observations), **costs}}
    if part in ("rel", "bound", "all"):
        summary["rel"] = evaluate_rel(settings, model, belief, initial, policies,
                                      workers=workers, continuous=part != "bound")
    if part in ("scenes", "bound", "all"):
        solved = Solved(policies["rel-sarsop"], corner)
        summary["scenes"] = run_scenes(settings, scenes, solved, out, workers=workers)
    if part in ("bound", "all"):
        summary["bound"] = bound_check(summary["rel"], summary["scenes"])
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if part in ("rel", "all"):
        plot_rel(summary, out)
    if "scenes" in summary:
        plot_scenes(summary, out)
    return summary
