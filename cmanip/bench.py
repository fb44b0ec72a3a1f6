"""``cmanip bench``: measurements, each reported as medians (and ratios against a baseline
measured in the same run where there is one) and optionally written as JSON."""

from __future__ import annotations

import argparse
from pathlib import Path

from cmanip.options import backend_of, runner_options, subcommand, write_json
from cmanip.pomdp import TRIAL_RULES
from cmanip.robustness import ROBUSTNESS_PARTS


def register(commands) -> None:
    bench = subcommand(commands, "bench", "measurements: plant time step, filters, POMDP "
                                          "solvers (point-based, DESPOT, Lat-DESPOT), "
                                          "visuo-tactile smoother")
    kinds = bench.add_subparsers(dest="bench", required=True, metavar="BENCH")
    step = subcommand(kinds, "timestep", "accuracy and speed per plant time step")
    step.add_argument("--steps", type=float, nargs="+",
                      default=[0.001, 0.002, 0.005, 0.01, 0.02], help="time steps (s)")
    step.add_argument("--repeats", type=int, default=3, help="timed runs per step")
    _json(step)
    step.set_defaults(handler=_timestep)

    mpf = subcommand(kinds, "mpf", "CPF/MPF update times, pushing-model throughput")
    mpf.add_argument("--repeats", type=int, default=30, help="timed updates per filter")
    mpf.add_argument("--seed", type=int, default=0, help="seeds the particles")
    _json(mpf)
    mpf.set_defaults(handler=_mpf)

    ce = subcommand(kinds, "configest", "configuration estimation: CPF and MPF-Ball update "
                                        "times per arm, projection cost, root finders, "
                                        "Drake's signed distance against the compiled one")
    ce.add_argument("--arm", nargs="+", default=["2dof", "3dof", "wam"],
                    help="arms (names or arm YAMLs)")
    ce.add_argument("--seed", type=int, default=0, help="seeds the experiment and filters")
    _json(ce)
    ce.set_defaults(handler=_configest)

    robust = subcommand(kinds, "robustness", "robustness, measured: malformed files of every "
                                             "kind, faults injected into every estimator, "
                                             "planner budgets under load, memory over long "
                                             "runs")
    robust.add_argument("--parts", nargs="+", choices=ROBUSTNESS_PARTS,
                        default=list(ROBUSTNESS_PARTS), help="what to measure")
    robust.add_argument("--limit-per-kind", type=int, default=None,
                        help="malformed: try at most this many mutants per file kind "
                             "(default: all, about 15,800 files in a minute)")
    robust.add_argument("--fault-trials", type=int, default=3,
                        help="faults: experiments per estimator family")
    runner_options(robust, resume=False)
    robust.add_argument("--decisions", type=int, default=200,
                        help="budgets: decisions per planner and load; memory: closed-loop "
                             "decisions are five times this")
    robust.add_argument("--budget-s", type=float, default=0.1,
                        help="budgets: wall-clock budget per decision (s)")
    robust.add_argument("--smoother-updates", type=int, default=10_000,
                        help="memory: smoother updates")
    robust.add_argument("--cache-dir", type=Path, default=Path("out/cache"),
                        help="budgets: where Lat-DESPOT's lattice IK table is kept")
    robust.add_argument("--seed", type=int, default=0, help="seeds every part")
    robust.add_argument("--no-progress", action="store_true", help="no progress bar")
    robust.add_argument("--fault-figure", type=Path, default=None,
                        help="faults: also draw each run's error against the recovery "
                             "bound to this PNG")
    _json(robust)
    robust.set_defaults(handler=_robustness)

    pomdp = subcommand(kinds, "pomdp", "point-based solver bounds on Tag and RockSample(7,8) "
                                       "over 300 s, against the C++ SARSOP's published runs")
    pomdp.add_argument("--quick", action="store_true", help="stop at 30 s")
    pomdp.add_argument("--trial-rule", choices=TRIAL_RULES, default="sarsop",
                       help="where the solver's trials stop (HSVI2's rule: the comparison)")
    _json(pomdp)
    pomdp.set_defaults(handler=_pomdp)

    lat = subcommand(kinds, "latdespot", "Lat-DESPOT's decisions on the Python and the "
                                         "compiled DESPOT engine, side by side")
    lat.add_argument("--scene", default="cul_de_sac", help="the scene (name or YAML)")
    lat.add_argument("--decisions", type=int, default=60, help="decisions timed per engine")
    lat.add_argument("--trials", type=int, default=30, help="DESPOT trials per decision")
    lat.add_argument("--seed", type=int, default=0, help="seeds the episodes")
    lat.add_argument("--cache-dir", type=Path, default=Path("out/cache"),
                     help="where the lattice's IK table is kept")
    lat.add_argument("--no-progress", action="store_true", help="no progress bars")
    _json(lat)
    lat.set_defaults(handler=_latdespot)

    despot = subcommand(kinds, "despot", "DESPOT on Tag, RockSample or a .pomdp file, beside "
                                         "the reference C++ DESPOT when it is built")
    despot.add_argument("--problem", nargs="+", default=["rocksample:7:8", "tag"],
                        help="problems: tag, rocksample:N:K or a .pomdp path")
    despot.add_argument("--seconds-per-step", type=float, nargs="+", default=[0.1, 1.0],
                        help="wall-clock budget per decision (s)")
    despot.add_argument("--episodes", type=int, default=100, help="episodes per budget")
    despot.add_argument("--steps", type=int, default=90, help="decisions per episode at most")
    despot.add_argument("--scenarios", type=int, default=500, help="DESPOT's K")
    despot.add_argument("--seed", type=int, default=0, help="episode e is seeded (seed, e)")
    despot.add_argument("--reference", type=Path, default=None,
                        help="a built reference DESPOT (its build folder) to run side by side")
    despot.add_argument("--no-progress", action="store_true", help="no progress bars")
    _json(despot)
    despot.set_defaults(handler=_despot)

    vt = subcommand(kinds, "visuotactile", "smoother update and relinearisation times")
    vt.add_argument("--log", type=Path, default=None,
                    help="time on this push log (default: a simulated standard run)")
    vt.add_argument("--object", default="rect1", help="the log's object")
    vt.add_argument("--seed", type=int, default=0, help="seeds the simulated run")
    _json(vt)
    vt.set_defaults(handler=_visuotactile)


def _json(parser) -> None:
    parser.add_argument("--json", type=Path, default=None, help="also write the report here")


def _timestep(args: argparse.Namespace) -> int:
    from experiments.timestep_bench import run_timestep_bench

    write_json(run_timestep_bench(args.steps, repeats=args.repeats), args.json)
    return 0


def _mpf(args: argparse.Namespace) -> int:
    from experiments.mpf_bench import run_mpf_bench

    write_json(run_mpf_bench(repeats=args.repeats, seed=args.seed), args.json)
    return 0


def _configest(args: argparse.Namespace) -> int:
    from experiments.configest_bench import run_configest_bench
    from models.arms.spec import ArmSpec
    from models.arms.world import ArmWorld

    for arm in args.arm:  # a bad arm file (or link) fails before anything runs
        ArmWorld(ArmSpec.load(arm))
    write_json(run_configest_bench(tuple(args.arm), seed=args.seed), args.json)
    return 0


def _robustness(args: argparse.Namespace) -> int:
    from cmanip.robustness import measure_robustness

    for name in ("limit_per_kind", "fault_trials", "decisions", "smoother_updates"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
    if "memory" in args.parts:
        from experiments.load_bench import MIN_MEMORY_STEPS

        if args.smoother_updates < MIN_MEMORY_STEPS or 5 * args.decisions < MIN_MEMORY_STEPS:
            raise ValueError(f"memory: --smoother-updates and five times --decisions must "
                             f"be >= {MIN_MEMORY_STEPS} (the growth is a slope over the "
                             f"run), got {args.smoother_updates} and {5 * args.decisions}")
    if not args.budget_s > 0:
        raise ValueError(f"--budget-s must be > 0, got {args.budget_s}")
    if args.fault_figure is not None and "faults" not in args.parts:
        raise ValueError("--fault-figure draws the faults part; add faults to --parts")
    if args.fault_figure is not None and args.fault_figure.suffix.lower() != ".png":
        raise ValueError(f"--fault-figure {args.fault_figure}: must end in .png")
    report = measure_robustness(
        args.parts, limit_per_kind=args.limit_per_kind, fault_trials=args.fault_trials,
        decisions=args.decisions, budget_s=args.budget_s,
        smoother_updates=args.smoother_updates, cache_dir=args.cache_dir, seed=args.seed,
        progress=not args.no_progress, backend=backend_of(args),
        fault_figure=args.fault_figure)
    write_json(report, args.json)
    return 0


def _pomdp(args: argparse.Namespace) -> int:
    from experiments.pomdp_bench import run_pomdp_bench

    write_json(run_pomdp_bench(quick=args.quick, trial_rule=args.trial_rule), args.json)
    return 0


def _despot(args: argparse.Namespace) -> int:
    from experiments.despot_bench import run_despot_bench
    from planning.pomdp.problems import load_problem

    if args.episodes < 2 or args.steps < 1 or args.scenarios < 1:
        raise ValueError("--episodes must be >= 2, --steps and --scenarios >= 1")
    if min(args.seconds_per_step) <= 0:
        raise ValueError("--seconds-per-step must be > 0")
    for problem in args.problem:  # a bad name or file fails before any episode runs
        load_problem(problem)
    if args.reference is not None and not args.reference.is_dir():
        raise ValueError(f"--reference {args.reference}: not a directory")
    write_json(run_despot_bench(args.problem, args.seconds_per_step, episodes=args.episodes,
                                steps=args.steps, seed=args.seed, scenarios=args.scenarios,
                                reference=args.reference, progress=not args.no_progress),
               args.json)
    return 0


def _latdespot(args: argparse.Namespace) -> int:
    from experiments.latdespot_bench import run_latdespot_bench
    from models.herb.scene import SceneSpec

    if args.decisions < 1 or args.trials < 1:
        raise ValueError("--decisions and --trials must be >= 1")
    SceneSpec.load(args.scene)  # a bad name or file fails before the problem is built
    write_json(run_latdespot_bench(args.scene, decisions=args.decisions, trials=args.trials,
                                   seed=args.seed, cache_dir=str(args.cache_dir),
                                   progress=not args.no_progress), args.json)
    return 0


def _visuotactile(args: argparse.Namespace) -> int:
    from experiments.visuotactile_bench import run_visuotactile_bench

    write_json(run_visuotactile_bench(args.log, args.seed, args.object), args.json)
    return 0
