"""``cmanip run``: one closed-loop episode, HERB pushing an object into the goal by touch in
one Drake diagram; and the options it shares with ``cmanip experiment closedloop``."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from cmanip.config import RunConfig, load_config, overridden, with_object, write_config
from cmanip.options import check_outlier_gate, setting_option, subcommand, wait_for_meshcat
from diagrams.herb.settings import (
    ESTIMATORS,
    LAT_DESPOT_MODELS,
    PLANNER_BELIEFS,
    PLANNERS,
    POLICIES,
    THESIS_BELIEF_MEANS,
    EpisodeSettings,
)
from planning.hand.solution import HandSolveSettings
from planning.lattice.pomdp import OUTSIDE_MODES

EPISODE = EpisodeSettings()
SOLVER = RunConfig().solver


EPISODE_OPTIONS = (
    ("--planner", EPISODE.planner,
     "the controller's planner: hand-relative (thesis ch. 6; pre-contact search, then the "
     "post-contact policy), or Lat-DESPOT over the configuration lattice (ch. 7)",
     {"choices": PLANNERS}),
    ("--lat-despot-trials", EPISODE.lat_despot_trials,
     "DESPOT trials per Lat-DESPOT decision (0: the wall-clock cap alone)", {"type": int}),
    ("--lat-despot-seconds", EPISODE.lat_despot_seconds,
     "Lat-DESPOT's wall-clock cap per decision (s)", {"type": float}),
    ("--lat-despot-model", EPISODE.lat_despot_model,
     "what Lat-DESPOT plans on: the discretised hand-relative model (the thesis) or the "
     "continuous pushing model", {"choices": LAT_DESPOT_MODELS}),
    ("--lat-despot-outside", EPISODE.lat_despot_outside,
     "with --lat-despot-model continuous, how the bounds value an object outside the "
     "planning region: the discrete model's absorbing sentinel, or the steps back to the "
     "region then the bounds there", {"choices": OUTSIDE_MODES}),
    ("--estimator", EPISODE.estimator,
     "the estimator's filter: manifold (MPF) or conventional (CPF)", {"choices": ESTIMATORS}),
    ("--outlier-gate", "none (the thesis)",
     "the estimator's outlier gate: a reading with evidence log p(o | b+) below this (< 0), "
     "which no dual explains, is propagated through unweighed (the fault bench: -30)",
     {"type": float}),
    ("--planner-belief", EPISODE.planner_belief,
     "the policy acts on the estimator's belief, or on its own filters as in the thesis "
     "(sec. 6.4.1)", {"choices": PLANNER_BELIEFS}),
    ("--on-infeasible", EPISODE.on_infeasible,
     "when the policy's action is infeasible: end the episode (the thesis' rule) or take "
     "the next-ranked feasible action", {"choices": ("stop", "next")}),
    ("--horizon", EPISODE.horizon, "decisions per episode", {"type": int}),
    ("--particles", EPISODE.particles, "estimator particles", {"type": int}),
    ("--plan-seconds", EPISODE.precontact.time_limit_s,
     "pre-contact search time limit (s; thesis: 20)", {"type": float}),
    ("--solve-seconds", SOLVER.solve_seconds,
     "point-based solver wall-time cap (s) when the policy is not cached", {"type": float}),
    ("--solve-trials", SOLVER.solve_trials,
     "stop the solver after this many search trials (a trial budget makes the policy "
     "machine-independent; 0: the time cap alone)", {"type": int}),
)
"""(flag, default, help, argparse keywords) of the episode and solver options."""


def add_episode_options(parser, *, policy: bool) -> None:
    """The episode options of ``run`` and ``experiment closedloop`` (each overrides the
    configuration's value only when given)."""
    parser.add_argument("--config", type=Path, default=None,
                        help="a YAML configuration (e.g. a run's DIR/config.yaml); the "
                             "options below override it")
    setting_option(parser, "--scene", EPISODE.scene, "scene name or path")
    setting_option(parser, "--object", EPISODE.object_name,
                   "object name or path, pushed and planned for (the thesis' real-robot "
                   "trials: a bottle)")
    if policy:
        setting_option(parser, "--policy", EPISODE.policy, "post-contact policy",
                       choices=POLICIES)
    for flag, default, text, kwargs in EPISODE_OPTIONS:
        setting_option(parser, flag, default, text, **kwargs)
    setting_option(parser, "--cache", RunConfig().cache_dir,
                   "where solved planning models are kept")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def override_episode(episode: EpisodeSettings, args: argparse.Namespace) -> EpisodeSettings:
    """``episode`` with the episode options given on the command line.

    Raises:
        ValueError: ``--outlier-gate`` not below 0 (named as the flag, before the settings
            name their field).
    """
    check_outlier_gate(args)
    episode = overridden(episode, args, {
        "scene": "scene", "object": "object_name", "policy": "policy",
        "estimator": "estimator", "outlier_gate": "estimator_outlier_log_evidence",
        "planner_belief": "planner_belief", "on_infeasible": "on_infeasible",
        "horizon": "horizon", "particles": "particles",
        "planner": "planner", "lat_despot_seconds": "lat_despot_seconds",
        "lat_despot_model": "lat_despot_model", "lat_despot_outside": "lat_despot_outside"})
    given = vars(args)
    if "lat_despot_trials" in given:
        episode = replace(episode, lat_despot_trials=given["lat_despot_trials"] or None)
    return replace(episode, precontact=overridden(episode.precontact, args,
                                                  {"plan_seconds": "time_limit_s"}))


def override_solver(solver: HandSolveSettings, args: argparse.Namespace) -> HandSolveSettings:
    """``solver`` with the solver options given on the command line."""
    given = vars(args)
    if "object" in given:
        solver = with_object(solver, given["object"])
    if "solve_seconds" in given:
        solver = replace(solver, solve_seconds=given["solve_seconds"])
    if "solve_trials" in given:
        solver = replace(solver, solve_trials=given["solve_trials"] or None)
    return solver


def solve(solver: HandSolveSettings, cache_dir: str, *, progress: bool):
    """The solved planning model (from the cache when it holds it)."""
    from planning.hand.solution import solve_hand_problem

    solution = solve_hand_problem(solver, cache_dir=Path(cache_dir), progress=progress)
    origin = "loaded from" if solution.loaded_from_cache else "solved and saved in"
    print(f"planning model ({len(solution.model.pomdp.states)} states) {origin} {cache_dir}",
          flush=True)
    return solution


def register(commands) -> None:
    run = subcommand(commands, "run", "one closed-loop episode: HERB pushes an object into "
                                      "the goal by touch, in one Drake diagram")
    add_episode_options(run, policy=True)
    setting_option(run, "--belief", THESIS_BELIEF_MEANS.index(EPISODE.belief_mean) + 1,
                   "initial belief of thesis sec. 6.5 (means 35 cm ahead at lateral offsets "
                   "-12, 0, +6 cm; 2 is the centre)", type=int, choices=(1, 2, 3))
    run.add_argument("--belief-mean", type=float, nargs=3, default=None,
                     metavar=("X_M", "Y_M", "THETA_DEG"),
                     help="initial belief mean in the hand frame instead of --belief's "
                          "(e.g. 0.2 -0.05 0 for the ch. 7 scenes, whose clutter lies about "
                          "35 cm ahead)")
    setting_option(run, "--seed", EPISODE.seed, "seeds the true pose, particles, sensors, "
                                                "filter and planner", type=int)
    run.add_argument("--out", type=Path, required=True,
                     help="output directory (summary.json, belief.png, replay.html, "
                          "trace.npz, config.yaml)")
    run.add_argument("--meshcat", action="store_true",
                     help="serve Meshcat live on localhost (prints the URL) and, when run "
                          "from a terminal, wait for Enter at the end")
    run.set_defaults(handler=_run)


def resolve_run(args: argparse.Namespace) -> RunConfig:
    """The run's configuration: ``--config`` (or the defaults), then the options given."""
    config = load_config(RunConfig, args.config)
    episode = override_episode(config.episode, args)
    given = vars(args)
    if "belief" in given:
        episode = replace(episode, belief_mean=THESIS_BELIEF_MEANS[given["belief"] - 1])
    if given.get("belief_mean") is not None:
        x, y, theta_deg = given["belief_mean"]
        episode = replace(episode, belief_mean=(x, y, float(np.deg2rad(theta_deg))))
    if "seed" in given:
        episode = replace(episode, seed=given["seed"])
    return RunConfig(episode, override_solver(config.solver, args),
                     given.get("cache", config.cache_dir))


def _run(args) -> int:
    from diagrams.herb.closed_loop import InfeasibleStart
    from diagrams.herb.episode import run_episode
    from diagrams.herb.report import write_episode
    from diagrams.meshcat import local_meshcat

    config = resolve_run(args)
    settings = config.episode
    solution = solve(config.solver, config.cache_dir, progress=not args.no_progress)
    meshcat = local_meshcat()
    if args.meshcat:
        print(f"Meshcat is live at {meshcat.web_url()}", flush=True)
    try:
        episode = run_episode(settings, solution, meshcat=meshcat,
                              progress=not args.no_progress, cache_dir=Path(config.cache_dir))
    except InfeasibleStart as err:
        print(f"cmanip: infeasible start: {err}", file=sys.stderr)
        return 3
    write_episode(episode, args.out)
    write_config(config, args.out)
    s = episode.summary
    outcome = "SUCCESS: the object is in the goal" if s["success"] else \
        f"FAILURE: the object is {100 * s['final_distance_to_goal_m']:.1f} cm from the goal"
    stop = s["stop_reason"]
    if stop == "no_feasible_action":
        stop = f"the next action is infeasible: {s['rejections'][-1]['reason']}"
    belief = (f"belief {THESIS_BELIEF_MEANS.index(settings.belief_mean) + 1}"
              if settings.belief_mean in THESIS_BELIEF_MEANS else
              f"belief mean {list(settings.belief_mean)}")
    planner = settings.policy if settings.planner == "hand" else settings.planner
    lattice = ""
    if "lattice" in s:
        lattice = (f"; lattice evaluated: {s['lattice']['edges_evaluated']} edges "
                   f"({s['lattice']['edge_fraction_evaluated']:.1%})")
        if s["lattice"]["executed_clearance_min_m"] is not None:
            lattice += (f"; closest arm pass "
                        f"{100 * s['lattice']['executed_clearance_min_m']:.1f} cm")
    print(f"{planner}/{settings.estimator}, {belief}, seed {settings.seed}: "
          f"{outcome} after {s['steps']} steps (stopped: {stop}); estimator RMSE mean "
          f"{100 * s['estimator_rmse_m']['mean']:.1f} cm; planning median "
          f"{s['planning_ms_median']:.1f} ms; {s['sim_time_s']:.1f} s simulated in "
          f"{s['wall_time_s']:.1f} s{lattice}")
    print(f"wrote {args.out}/replay.html, summary.json, belief.png, config.yaml")
    if args.meshcat:
        wait_for_meshcat(meshcat.web_url())
    return 0
