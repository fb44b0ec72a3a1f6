"""The ``cmanip`` command line.

Subcommands:
    simulate   push an object straight ahead in a scene; writes replay.html, summary.json,
               tactile.png.
    bench      measurements (``bench timestep``: accuracy and speed per plant time step;
               ``bench mpf``: filter update times and the pushing model's throughput;
               ``bench pomdp``: point-based solver bounds on Tag and RockSample).
    experiment studies that reproduce the seeds (``experiment mpf``: thesis sec. 4.3;
               ``experiment pushval``: the planar pushing model against Drake;
               ``experiment handplan``: planning by touch, thesis sec. 6.4).
    pomdp      tabular POMDPs: ``pomdp write`` a built-in benchmark as a Cassandra ``.pomdp``
               file; ``pomdp solve`` any ``.pomdp`` file with the point-based solver.
    push       seed 003's pusher-slider: ``push simulate`` a procedure into a sensor log,
               ``push estimate`` any log (see :mod:`cmanip.push`); its study is
               ``experiment visuotactile`` and its bench ``bench visuotactile``.
    run        one closed-loop episode: HERB pushes an object into the goal by touch, in one
               Drake diagram (see :mod:`cmanip.run`); its study is
               ``experiment closedloop``.
    scenes     list the built-in scenes, objects and tactile layouts.

Studies (``experiments/``) are imported lazily, only by the subcommands that run them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cmanip import push as push_commands
from cmanip import run as run_commands
from models.config import ConfigError, builtin_names

# the point-based solver's trial rules (planning.pomdp.point_based.PointBasedSolver.TRIAL_RULES;
# not imported here, to keep `cmanip --help` free of the compiled solver)
TRIAL_RULES = ("sarsop", "hsvi")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="cmanip", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)

    sim = commands.add_parser("simulate", help="push an object straight ahead")
    sim.add_argument("--scene", default="empty", help="built-in scene name or path to a YAML")
    sim.add_argument("--object", default=None,
                     help="object name or path (default: the scene's object)")
    sim.add_argument("--push-distance", type=float, default=0.3, help="palm travel (m)")
    sim.add_argument("--hand-speed", type=float, default=0.05, help="palm speed (m/s)")
    sim.add_argument("--tactile", default="default", help="tactile layout name or path")
    sim.add_argument("--time-step", type=float, default=None, help="plant time step (s)")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--out", type=Path, required=True, help="output directory")
    sim.add_argument("--meshcat", action="store_true",
                     help="serve Meshcat live on localhost (prints the URL) and wait at the end")
    sim.add_argument("--no-progress", action="store_true")

    bench = commands.add_parser("bench", help="measurements")
    bench_kinds = bench.add_subparsers(dest="bench", required=True)
    step = bench_kinds.add_parser("timestep", help="accuracy and speed per plant time step")
    step.add_argument("--steps", type=float, nargs="+", default=[0.001, 0.002, 0.005, 0.01, 0.02])
    step.add_argument("--repeats", type=int, default=3)
    step.add_argument("--json", type=Path, default=None)

    mpf_bench = bench_kinds.add_parser("mpf", help="CPF/MPF update times, pushing throughput")
    mpf_bench.add_argument("--repeats", type=int, default=30, help="timed updates per filter")
    mpf_bench.add_argument("--seed", type=int, default=0)
    mpf_bench.add_argument("--json", type=Path, default=None)

    pomdp_bench = bench_kinds.add_parser(
        "pomdp", help="point-based solver bounds on Tag and RockSample(7,8)")
    pomdp_bench.add_argument("--quick", action="store_true", help="stop at 30 s")
    pomdp_bench.add_argument("--json", type=Path, default=None)
    pomdp_bench.add_argument("--trial-rule", choices=TRIAL_RULES, default="sarsop",
                             help="where the solver's trials stop (HSVI2's rule: the "
                                  "comparison)")

    experiment = commands.add_parser("experiment", help="studies that reproduce the seeds")
    studies = experiment.add_subparsers(dest="study", required=True)
    mpf = studies.add_parser("mpf", help="CPF vs MPF and the manifold representations")
    mpf.add_argument("--part", default="compare",
                     choices=["compare", "resolution", "rate", "representations", "mixing",
                              "all"])
    mpf.add_argument("--trials", type=int, default=100)
    mpf.add_argument("--seed", type=int, default=0)
    mpf.add_argument("--workers", type=int, default=1, help="processes")
    mpf.add_argument("--object", default="box", help="object name or path to a YAML file")
    mpf.add_argument("--sensors", default="medium",
                     help="planar sensor layout (low, medium, high or a YAML path)")
    mpf.add_argument("--push-distance", type=float, default=0.5, help="hand travel (m)")
    mpf.add_argument("--out", type=Path, required=True)
    mpf.add_argument("--no-progress", action="store_true")

    pushval = studies.add_parser("pushval",
                                 help="planar pushing model vs Drake on 20 straight pushes")
    pushval.add_argument("--push-distance", type=float, default=0.15, help="hand travel (m)")
    pushval.add_argument("--out", type=Path, required=True)
    pushval.add_argument("--no-progress", action="store_true")

    handplan = studies.add_parser("handplan",
                                  help="QMDP vs point-based post-contact policies, "
                                       "pre-contact A*, sensor coverage (thesis ch. 6)")
    handplan.add_argument("--part", default="post-contact",
                          choices=["post-contact", "full", "coverage", "all"])
    handplan.add_argument("--trials", type=int, default=200,
                          help="continuous-model trials per policy (discrete: twice as many)")
    handplan.add_argument("--seed", type=int, default=0)
    handplan.add_argument("--solve-seconds", type=float, default=300.0,
                          help="point-based solver budget (s)")
    handplan.add_argument("--solve-trials", type=int, default=None,
                          help="also stop the solver after this many search trials "
                               "(reproducible across machines)")
    handplan.add_argument("--plan-seconds", type=float, default=20.0,
                          help="pre-contact search budget per belief (s)")
    handplan.add_argument("--search-until-contact", action="store_true",
                          help="pre-contact search ignores the 85 %% trust-region stop")
    handplan.add_argument("--horizon", type=int, default=50, help="post-contact steps")
    handplan.add_argument("--problem", type=Path, default=None,
                          help="YAML of HandProblemSpec fields (trust region, cells, goal, "
                               "discount, samples per state)")
    handplan.add_argument("--quick", action="store_true",
                          help="a small problem (coarse trust region, few samples) to try it out")
    handplan.add_argument("--out", type=Path, required=True)

    pomdp = commands.add_parser("pomdp", help="write or solve Cassandra .pomdp files")
    pomdp_kinds = pomdp.add_subparsers(dest="pomdp", required=True)
    write = pomdp_kinds.add_parser("write", help="write a built-in benchmark as .pomdp")
    write.add_argument("name", choices=["tiger", "tag", "rocksample_7_8"])
    write.add_argument("--out", type=Path, required=True, help="the .pomdp file to write")
    solve = pomdp_kinds.add_parser("solve", help="solve a .pomdp file (point-based solver)")
    solve.add_argument("file", type=Path)
    solve.add_argument("--seconds", type=float, default=60.0, help="solver budget (s)")
    solve.add_argument("--out", type=Path, default=None, help="write the policy (.npz)")
    solve.add_argument("--trial-rule", choices=TRIAL_RULES, default="sarsop",
                       help="where the solver's trials stop")

    commands.add_parser("scenes", help="list built-in scenes, objects and tactile layouts")
    push_commands.add_commands(commands, studies, bench_kinds)
    run_commands.add_commands(commands, studies)

    args = parser.parse_args(argv)
    try:
        for module in (push_commands, run_commands):
            handled = module.run(args)
            if handled is not None:
                return handled
        if args.command == "simulate":
            return _simulate(args)
        if args.command == "bench" and args.bench == "timestep":
            from experiments.timestep_bench import run_timestep_bench

            report = run_timestep_bench(args.steps, repeats=args.repeats)
            if args.json:
                args.json.write_text(json.dumps(report, indent=2) + "\n")
            return 0
        if args.command == "bench" and args.bench == "mpf":
            from experiments.mpf_bench import run_mpf_bench

            report = run_mpf_bench(repeats=args.repeats, seed=args.seed)
            if args.json:
                args.json.write_text(json.dumps(report, indent=2) + "\n")
            return 0
        if args.command == "bench" and args.bench == "pomdp":
            from experiments.pomdp_bench import run_pomdp_bench

            report = run_pomdp_bench(quick=args.quick, trial_rule=args.trial_rule)
            if args.json:
                args.json.write_text(json.dumps(report, indent=2) + "\n")
            return 0
        if args.command == "pomdp":
            return _pomdp(args)
        if args.command == "experiment" and args.study == "pushval":
            return _experiment_pushval(args)
        if args.command == "experiment" and args.study == "handplan":
            return _experiment_handplan(args)
        if args.command == "experiment":
            return _experiment_mpf(args)
        for kind in ("scenes", "objects", "tactile", "planar_sensors"):
            print(f"{kind}: {', '.join(builtin_names(kind))}")
        return 0
    except (ConfigError, ValueError, OSError) as err:
        print(f"cmanip: error: {err}", file=sys.stderr)
        return 2


def _pomdp(args: argparse.Namespace) -> int:
    from planning.pomdp.benchmarks import rock_sample, tag, tiger
    from planning.pomdp.cassandra import read_pomdp, write_pomdp
    from planning.pomdp.point_based import PointBasedSolver

    if args.pomdp == "write":
        model = {"tiger": tiger, "tag": tag, "rocksample_7_8": rock_sample}[args.name]()
        write_pomdp(model, args.out)
        S, A, n_obs = model.shape
        print(f"wrote {args.out}: {S} states, {A} actions, {n_obs} observations, "
              f"discount {model.discount}")
        return 0
    if args.seconds <= 0:
        raise ValueError(f"--seconds must be > 0, got {args.seconds}")
    model = read_pomdp(args.file)
    solver = PointBasedSolver(model, trial_rule=args.trial_rule)
    policy = solver.solve(args.seconds)
    lower, upper = solver.report.history[-1][1:]
    print(f"{args.file}: bounds at the initial belief after {args.seconds:g} s: "
          f"[{lower:.4f}, {upper:.4f}]; {len(policy.alphas)} alpha-vectors")
    if args.out:
        policy.save(args.out)
        print(f"wrote {args.out}")
    return 0


def _experiment_mpf(args: argparse.Namespace) -> int:
    from experiments.mpf_study import TrialSettings, run_study
    from models.objects import ObjectSpec
    from models.planar.hand import PlanarSensorLayout

    if args.trials < 2 or args.workers < 1:
        raise ValueError("--trials must be >= 2 and --workers >= 1")
    if not 0.0 < args.push_distance <= 2.0:
        raise ValueError(f"--push-distance {args.push_distance} m is outside (0, 2] m")
    ObjectSpec.load(args.object)  # fail early, with the file and field, on a bad input
    PlanarSensorLayout.load(args.sensors)
    base = TrialSettings(object=args.object, sensors=args.sensors,
                         push_distance_m=args.push_distance)
    summary = run_study(args.part, base, args.trials, args.seed, args.workers, args.out,
                        progress=not args.no_progress)
    parts = summary["parts"] if args.part == "all" else {args.part: summary}
    for name, part in parts.items():
        print(f"{name}:")
        for label, entry in part["filters"].items():
            fail = entry.get("sampling_failure_rate")
            extra = (f", sampling failures {fail:.0%} ("
                     f"{entry['sampling_failure_rate_correct_readings']:.0%} on correct readings)"
                     if fail is not None else "")
            print(f"  {label:28s} post-contact RMSE {entry['post_contact_rmse_cm']:.2f} cm, "
                  f"{entry['post_contact_rmse_deg']:.1f} deg{extra}")
    print(f"wrote {args.out}/summary.json and figures")
    return 0


def _experiment_handplan(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from experiments.handplan_study import HandplanSettings, quick_settings, run_study
    from planning.hand.discretization import HandProblemSpec
    from planning.hand.precontact import PreContactSettings

    if args.trials < 2 or args.horizon < 1:
        raise ValueError("--trials must be >= 2 and --horizon >= 1")
    if args.solve_seconds <= 0 or args.plan_seconds <= 0:
        raise ValueError("--solve-seconds and --plan-seconds must be > 0")
    spec = HandProblemSpec.load(args.problem) if args.problem else HandProblemSpec()
    settings = HandplanSettings(trials=args.trials, seed=args.seed,
                                solve_seconds=args.solve_seconds,
                                solve_trials=args.solve_trials, horizon=args.horizon,
                                precontact=PreContactSettings(
                                    time_limit_s=args.plan_seconds,
                                    trust_mass_stop=None if args.search_until_contact else 0.85),
                                spec=spec)
    if args.quick:
        settings = quick_settings(settings)
        settings = replace(settings, precontact=replace(
            settings.precontact, time_limit_s=args.plan_seconds,
            trust_mass_stop=None if args.search_until_contact else 0.85))
    summary = run_study(args.part, settings, args.out)
    for key, label in (("post_contact_discrete", "post-contact, discrete model"),
                       ("post_contact", "post-contact, continuous model"),
                       ("full", "full policy, continuous model")):
        for name, r in summary.get(key, {}).items():
            line = (f"  {label:32s} {name:6s} value {r['discounted_value']:7.2f} "
                    f"+- {r['discounted_value_ci95']:.2f}")
            if "success_rate" in r:
                lo, hi = r["success_rate_ci95"]
                line += f", success {r['success_rate']:.0%} [{lo:.0%}, {hi:.0%}]"
            print(line)
    for sensors, c in summary.get("coverage", {}).items():
        obs = c["observations"]
        print(f"  coverage {sensors}: {obs['feasible']} of {obs['possible']} contact readings "
              f"feasible; full-policy success " + ", ".join(
                  f"{n} {r['success_rate']:.0%}" for n, r in c["full"].items()))
    print(f"wrote {args.out}/summary.json and figures")
    return 0


def _experiment_pushval(args: argparse.Namespace) -> int:
    from experiments.push_validation import run_push_validation

    if not 0.0 < args.push_distance <= 0.4:
        raise ValueError(f"--push-distance {args.push_distance} m is outside (0, 0.4] m")
    s = run_push_validation(args.out, push_distance_m=args.push_distance,
                            progress=not args.no_progress)
    for case in s["cases"]:
        print(f"  y {case['lateral_offset_m']:+.2f} m, theta {case['orientation_deg']:+5.0f} deg: "
              f"rotation Drake {case['rotation_drake_deg']:+6.1f} deg, planar "
              f"{case['rotation_planar_deg']:+6.1f} deg; position difference "
              f"{case['position_difference_m'] * 100:.1f} cm")
    print(f"rotation direction agrees in {s['rotation_direction_agreement']} of "
          f"{s['case_count']} cases; median position difference "
          f"{s['position_difference_m_median'] * 100:.1f} cm, median rotation difference "
          f"{s['rotation_difference_deg_median']:.1f} deg")
    print(f"wrote {args.out}/summary.json and push_validation.png")
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from pydrake.geometry import Meshcat

    from diagrams.herb.straight_push import InfeasiblePush, run_straight_push, write_outputs
    from models.contact import SimulationConfig
    from models.herb.scene import SceneSpec
    from models.herb.tactile import TactileLayout

    if not 0.0 < args.push_distance <= 2.0:
        raise ValueError(f"--push-distance {args.push_distance} m is outside (0, 2] m")
    if not 0.0 < args.hand_speed <= 1.0:
        raise ValueError(f"--hand-speed {args.hand_speed} m/s is outside (0, 1] m/s")
    scene = SceneSpec.load(args.scene, object_override=args.object)
    layout = TactileLayout.load(args.tactile)
    sim = SimulationConfig() if args.time_step is None else SimulationConfig(args.time_step)
    meshcat = Meshcat()
    if args.meshcat:
        print(f"Meshcat is live at {meshcat.web_url()}", flush=True)
    try:
        outcome = run_straight_push(scene, args.push_distance, layout=layout, sim=sim,
                                    hand_speed_m_per_s=args.hand_speed, seed=args.seed,
                                    meshcat=meshcat, progress=not args.no_progress)
    except InfeasiblePush as err:
        print(f"cmanip: infeasible push: {err}", file=sys.stderr)
        return 3
    write_outputs(outcome, args.out)
    s = outcome.summary
    print(f"{s['scene']}/{s['object']}: pushed {s['push_distance_m']:.2f} m; object moved "
          f"{s['object_displacement_m']:.3f} m; {s['sim_time_s']:.1f} s simulated in "
          f"{s['wall_time_s']:.1f} s (real-time factor {s['real_time_factor']:.2f})")
    fired = {k: v for k, v in s["contact_counts"].items() if v}
    print(f"patches that read contact (samples): {fired or 'none'}")
    print(f"wrote {args.out}/replay.html, summary.json, tactile.png")
    if args.meshcat:
        input("Meshcat stays up until you press Enter... ")
    return 0


if __name__ == "__main__":
    sys.exit(main())
