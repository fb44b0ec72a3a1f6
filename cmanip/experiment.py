"""``cmanip experiment``: the studies that reproduce the published figures and tables,
each writing ``summary.json`` and PNGs into ``--out``.

    mpf           CPF vs MPF and the manifold representations (Koval et al. 2013; thesis 4.3)
    pushval       the planar pushing model against Drake on 20 straight pushes
    handplan      QMDP vs point-based post-contact policies, pre-contact A* (thesis ch. 6)
    closedloop    closed-loop episodes in Drake from the thesis' three initial beliefs (6.5)
    visuotactile  vision + touch smoothing vs EKF and vision (Yu and Rodriguez 2018)
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from cmanip.config import ClosedLoopStudyConfig, load_config, write_config
from cmanip.options import setting_option, subcommand
from cmanip.run import add_episode_options, override_episode, override_solver, solve
from diagrams.herb.settings import POLICIES
from experiments.closedloop_study import ClosedLoopSettings
from experiments.handplan_study import HandplanSettings
from experiments.mpf_study import PARTS as MPF_PARTS
from experiments.mpf_study import TrialSettings
from experiments.visuotactile_study import VisuotactileSettings

MPF = TrialSettings()
HANDPLAN = HandplanSettings()
CLOSEDLOOP = ClosedLoopSettings()
VISUOTACTILE = VisuotactileSettings()


def register(commands) -> None:
    experiment = subcommand(commands, "experiment", "studies that reproduce the published "
                                                    "figures and tables")
    studies = experiment.add_subparsers(dest="study", required=True, metavar="STUDY")
    mpf = subcommand(studies, "mpf", "CPF vs MPF and the manifold representations "
                                     "(thesis sec. 4.3)")
    mpf.add_argument("--part", default="compare", choices=[*MPF_PARTS, "all"],
                     help="which figure (all: every part into its own folder)")
    mpf.add_argument("--trials", type=int, default=100, help="trials per condition")
    mpf.add_argument("--seed", type=int, default=0, help="study seed; trial j is seeded "
                                                         "from (seed, j)")
    mpf.add_argument("--workers", type=int, default=1, help="processes")
    mpf.add_argument("--object", default=MPF.object, help="object name or path to a YAML")
    mpf.add_argument("--sensors", default=MPF.sensors,
                     help="planar sensor layout (low, medium, high or a YAML path)")
    mpf.add_argument("--push-distance", type=float, default=MPF.push_distance_m,
                     help="hand travel (m)")
    mpf.add_argument("--out", type=Path, required=True, help="output directory")
    mpf.add_argument("--no-progress", action="store_true", help="no progress bars")
    mpf.set_defaults(handler=_mpf)

    pushval = subcommand(studies, "pushval",
                         "planar pushing model vs Drake on 20 straight pushes")
    pushval.add_argument("--push-distance", type=float, default=0.15, help="hand travel (m)")
    pushval.add_argument("--out", type=Path, required=True, help="output directory")
    pushval.add_argument("--no-progress", action="store_true", help="no progress bars")
    pushval.set_defaults(handler=_pushval)

    handplan = subcommand(studies, "handplan", "QMDP vs point-based post-contact policies, "
                                               "pre-contact A*, sensor coverage (thesis ch. 6)")
    handplan.add_argument("--part", default="post-contact",
                          choices=["post-contact", "full", "coverage", "all"],
                          help="which comparison")
    handplan.add_argument("--trials", type=int, default=HANDPLAN.trials,
                          help="continuous-model trials per policy (discrete: twice as many)")
    handplan.add_argument("--seed", type=int, default=HANDPLAN.seed, help="master seed")
    handplan.add_argument("--solve-seconds", type=float, default=HANDPLAN.solve_seconds,
                          help="point-based solver budget (s)")
    handplan.add_argument("--solve-trials", type=int, default=HANDPLAN.solve_trials,
                          help="also stop the solver after this many search trials "
                               "(reproducible across machines)")
    handplan.add_argument("--plan-seconds", type=float,
                          default=HANDPLAN.precontact.time_limit_s,
                          help="pre-contact search budget per belief (s)")
    handplan.add_argument("--search-until-contact", action="store_true",
                          help="pre-contact search ignores the 85 %% trust-region stop")
    handplan.add_argument("--horizon", type=int, default=HANDPLAN.horizon,
                          help="post-contact steps")
    handplan.add_argument("--problem", type=Path, default=None,
                          help="YAML of HandProblemSpec fields (trust region, cells, goal, "
                               "discount, samples per state; default: the thesis' problem)")
    handplan.add_argument("--quick", action="store_true",
                          help="a small problem (coarse trust region, few samples) to try it out")
    handplan.add_argument("--out", type=Path, required=True, help="output directory")
    handplan.set_defaults(handler=_handplan)

    closedloop = subcommand(studies, "closedloop", "closed-loop episodes from the thesis' "
                                                   "three initial beliefs, in Drake (sec. 6.5)")
    add_episode_options(closedloop, policy=False)
    setting_option(closedloop, "--policy", "both", "which post-contact policies",
                   choices=(*POLICIES, "both"))
    setting_option(closedloop, "--trials", CLOSEDLOOP.trials,
                   "episodes per policy, spread over the three beliefs", type=int)
    setting_option(closedloop, "--seed", CLOSEDLOOP.seed,
                   "study seed; episode j is seeded from (seed, j)", type=int)
    closedloop.add_argument("--out", type=Path, required=True,
                            help="output directory (summary.json, closedloop.png, "
                                 "config.yaml)")
    closedloop.set_defaults(handler=_closedloop)

    vt = subcommand(studies, "visuotactile",
                    "vision + touch smoothing vs EKF and vision (Yu and Rodriguez 2018)")
    vt.add_argument("--part", default="methods",
                    choices=["noise", "methods", "shapes", "surfaces", "costs", "timing",
                             "all"], help="which comparison")
    vt.add_argument("--trials", type=int, default=VISUOTACTILE.trials,
                    help="runs per condition (at least 2)")
    vt.add_argument("--seed", type=int, default=VISUOTACTILE.seed, help="master seed")
    vt.add_argument("--noise-trials", type=int, default=VISUOTACTILE.noise_trials,
                    help="training runs for the noise identification")
    vt.add_argument("--rig", type=Path, default=None,
                    help="rig YAML (default: the built-in pusher_slider.yaml)")
    vt.add_argument("--out", type=Path, required=True, help="output directory")
    vt.add_argument("--no-progress", action="store_true", help="no progress bars")
    vt.set_defaults(handler=_visuotactile)


def _mpf(args: argparse.Namespace) -> int:
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


def _pushval(args: argparse.Namespace) -> int:
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


def _handplan(args: argparse.Namespace) -> int:
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


def _closedloop(args: argparse.Namespace) -> int:
    from experiments.closedloop_study import run_closedloop_study

    config = resolve_closedloop(args)
    solution = solve(config.solver, config.cache_dir, progress=not args.no_progress)
    summary = run_closedloop_study(config.study, solution, args.out,
                                   progress=not args.no_progress)
    write_config(config, args.out)
    for name, result in summary["policies"].items():
        lo, hi = result["success_rate_ci95"]
        print(f"{name}: success {result['successes']}/{result['trials']} "
              f"({100 * result['success_rate']:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}]); "
              f"infeasible actions executed {result['infeasible_actions']}; planning median "
              f"{result['planning_ms_median']:.1f} ms")
    print(f"wrote {args.out}/summary.json, closedloop.png, config.yaml")
    return 0


def resolve_closedloop(args: argparse.Namespace) -> ClosedLoopStudyConfig:
    """The study's configuration: ``--config`` (or the defaults), then the options given."""
    config = load_config(ClosedLoopStudyConfig, args.config)
    given = vars(args)
    study = replace(config.study, episode=override_episode(config.study.episode, args))
    if "policy" in given:
        study = replace(study, policies=POLICIES if given["policy"] == "both"
                        else (given["policy"],))
    for option in ("trials", "seed"):
        if option in given:
            study = replace(study, **{option: given[option]})
    return ClosedLoopStudyConfig(study, override_solver(config.solver, args),
                                 given.get("cache", config.cache_dir))


def _visuotactile(args) -> int:
    from experiments.visuotactile_study import VisuotactileSettings, run_study

    if args.trials < 2 or args.noise_trials < 1:
        raise ValueError("--trials must be >= 2 and --noise-trials >= 1")
    settings = VisuotactileSettings(trials=args.trials, seed=args.seed,
                                    noise_trials=args.noise_trials,
                                    rig=str(args.rig) if args.rig else None)
    summaries = run_study(args.part, settings, args.out, progress=not args.no_progress)
    for part, summary in summaries.items():
        print(f"{part}:")
        blocks = summary.get("conditions") or {"": summary.get("methods", {})}
        for condition, methods in blocks.items():
            for name, entry in methods.items():
                if "rmse_mm" not in entry:
                    print(f"  {name:42s} " + ", ".join(f"{k} {v:.3g}" for k, v in entry.items()))
                    continue
                mm, deg = entry["rmse_mm"], entry["rmse_deg"]
                if mm["mean"] is None:
                    print(f"  {condition:12s} {name:42s} failed")
                    continue
                print(f"  {condition:12s} {name:42s} {mm['mean']:5.1f} +- {mm['std']:4.1f} mm, "
                      f"{deg['mean']:5.2f} +- {deg['std']:4.2f} deg")
        if part == "noise":
            print(f"  limit surface c {summary['c_m'] * 1e3:.1f} mm (uniform pressure "
                  f"{summary['c_uniform_pressure_m'] * 1e3:.1f} mm)")
    print(f"wrote {args.out}/summary.json and figures")
    return 0
