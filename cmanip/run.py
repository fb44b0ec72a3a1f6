"""``cmanip run`` (one closed-loop episode) and ``cmanip experiment closedloop``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

DEFAULT_CACHE = Path("out/cache")


def add_commands(commands, studies) -> None:
    run = commands.add_parser("run", help="one closed-loop episode: HERB pushes by touch")
    run.add_argument("--scene", default="closed_loop", help="scene name or path")
    run.add_argument("--object", default="bottle",
                     help="object name or path (the thesis' real-robot trials: a bottle)")
    run.add_argument("--policy", choices=("qmdp", "pomdp"), default="pomdp")
    run.add_argument("--estimator", choices=("mpf", "cpf"), default="mpf")
    run.add_argument("--belief", type=int, choices=(1, 2, 3), default=2,
                     help="initial belief of thesis sec. 6.5 (means 35 cm ahead at lateral "
                          "offsets -12, 0, +6 cm)")
    run.add_argument("--on-infeasible", choices=("stop", "next"), default="stop")
    _common(run)
    run.add_argument("--out", type=Path, required=True)
    run.add_argument("--meshcat", action="store_true",
                     help="serve Meshcat live on localhost (prints the URL) and wait at the end")

    study = studies.add_parser("closedloop", help="closed-loop episodes from the thesis' three "
                                                  "initial beliefs, in Drake (sec. 6.5)")
    study.add_argument("--policy", choices=("qmdp", "pomdp", "both"), default="both")
    study.add_argument("--trials", type=int, default=30,
                       help="episodes per policy, spread over the three beliefs")
    study.add_argument("--object", default="bottle", help="object name or path")
    study.add_argument("--estimator", choices=("mpf", "cpf"), default="mpf")
    study.add_argument("--on-infeasible", choices=("stop", "next"), default="stop")
    _common(study)
    study.add_argument("--out", type=Path, required=True)


def _common(parser) -> None:
    parser.add_argument("--planner-belief", choices=("estimator", "thesis"), default="estimator",
                        help="the policy acts on the estimator's belief, or on its own filters "
                             "as in the thesis (sec. 6.4.1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--horizon", type=int, default=30, help="decisions per episode")
    parser.add_argument("--particles", type=int, default=500)
    parser.add_argument("--solve-seconds", type=float, default=600.0,
                        help="point-based solver wall-time cap (s) when the policy is not "
                             "cached")
    parser.add_argument("--solve-trials", type=int, default=400,
                        help="stop the solver after this many search trials (about 60 s for "
                             "the bottle; a trial budget makes the policy machine-independent; "
                             "0: no trial budget)")
    parser.add_argument("--plan-seconds", type=float, default=20.0,
                        help="pre-contact search time limit (s; thesis: 20)")
    parser.add_argument("--cache", type=Path, default=DEFAULT_CACHE,
                        help="where solved planning models are kept")
    parser.add_argument("--no-progress", action="store_true")


def run(args: argparse.Namespace) -> int | None:
    """Handle the commands of this module; ``None`` when ``args`` is another command's."""
    if args.command == "run":
        return _run(args)
    if args.command == "experiment" and args.study == "closedloop":
        return _study(args)
    return None


def _solution(args, object_name: str):
    from planning.hand.solution import HandSolveSettings, solve_hand_problem

    settings = HandSolveSettings(object_name=object_name, solve_seconds=args.solve_seconds,
                                 solve_trials=args.solve_trials or None)
    solution = solve_hand_problem(settings, cache_dir=args.cache,
                                  progress=not args.no_progress)
    origin = "loaded from" if solution.loaded_from_cache else "solved and saved in"
    print(f"planning model ({len(solution.model.pomdp.states)} states) {origin} {args.cache}",
          flush=True)
    return solution


def _run(args) -> int:
    from pydrake.geometry import Meshcat

    from diagrams.herb.episode import InfeasibleStart, run_episode
    from diagrams.herb.report import write_episode
    from diagrams.herb.settings import THESIS_BELIEF_MEANS, EpisodeSettings
    from planning.hand.precontact import PreContactSettings

    settings = EpisodeSettings(
        scene=args.scene, object_name=args.object, policy=args.policy,
        estimator=args.estimator, planner_belief=args.planner_belief,
        belief_mean=THESIS_BELIEF_MEANS[args.belief - 1],
        particles=args.particles, horizon=args.horizon, on_infeasible=args.on_infeasible,
        precontact=PreContactSettings(time_limit_s=args.plan_seconds), seed=args.seed)
    solution = _solution(args, args.object)
    meshcat = Meshcat()
    if args.meshcat:
        print(f"Meshcat is live at {meshcat.web_url()}", flush=True)
    try:
        episode = run_episode(settings, solution, meshcat=meshcat,
                              progress=not args.no_progress)
    except InfeasibleStart as err:
        print(f"cmanip: infeasible start: {err}", file=sys.stderr)
        return 3
    write_episode(episode, args.out)
    s = episode.summary
    outcome = "SUCCESS: the object is in the goal" if s["success"] else \
        f"FAILURE: the object is {100 * s['final_distance_to_goal_m']:.1f} cm from the goal"
    stop = s["stop_reason"]
    if stop == "no_feasible_action":
        stop = f"the next action is infeasible: {s['rejections'][-1]['reason']}"
    print(f"{args.policy}/{args.estimator}, belief {args.belief}, seed {args.seed}: {outcome} "
          f"after {s['steps']} steps (stopped: {stop}); estimator RMSE mean "
          f"{100 * s['estimator_rmse_m']['mean']:.1f} cm; planning median "
          f"{s['planning_ms_median']:.1f} ms; {s['sim_time_s']:.1f} s simulated in "
          f"{s['wall_time_s']:.1f} s")
    print(f"wrote {args.out}/replay.html, summary.json, belief.png")
    if args.meshcat:
        input("Meshcat stays up until you press Enter... ")
    return 0


def _study(args) -> int:
    from experiments.closedloop_study import ClosedLoopSettings, run_closedloop_study

    if args.trials < 1:
        raise ValueError(f"--trials must be >= 1, got {args.trials}")
    policies = ("qmdp", "pomdp") if args.policy == "both" else (args.policy,)
    settings = ClosedLoopSettings(
        policies=policies, trials=args.trials, seed=args.seed, estimator=args.estimator,
        planner_belief=args.planner_belief, object_name=args.object,
        horizon=args.horizon, particles=args.particles, on_infeasible=args.on_infeasible,
        plan_seconds=args.plan_seconds)
    solution = _solution(args, args.object)
    summary = run_closedloop_study(settings, solution, args.out,
                                   progress=not args.no_progress)
    for name, result in summary["policies"].items():
        lo, hi = result["success_rate_ci95"]
        print(f"{name}: success {result['successes']}/{result['trials']} "
              f"({100 * result['success_rate']:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}]); "
              f"infeasible actions executed {result['infeasible_actions']}; planning median "
              f"{result['planning_ms_median']:.1f} ms")
    print(f"wrote {args.out}/summary.json, closedloop.png")
    return 0
