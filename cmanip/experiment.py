"""``cmanip experiment``: the studies that reproduce the published figures and tables,
each writing ``summary.json`` and PNGs into ``--out``.

    mpf           CPF vs MPF and the manifold representations (Koval et al. 2013; thesis 4.3)
    pushval       the planar pushing model against Drake on 20 straight pushes
    handplan      QMDP vs point-based post-contact policies, pre-contact A* (thesis ch. 6)
    closedloop    closed-loop episodes in Drake from the thesis' three initial beliefs (6.5)
    visuotactile  vision + touch smoothing vs EKF and vision (Yu and Rodriguez 2018)
    latdespot     thesis ch. 7: Rel-QMDP, Rel-SARSOP and Rel-DESPOT (sec. 7.3.3)
    configest     thesis ch. 5: robot configuration estimation, CPF vs MPF projections
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from cmanip.config import (
    ClosedLoopStudyConfig,
    HandplanStudyConfig,
    LatDespotStudyConfig,
    MpfStudyConfig,
    VisuotactileStudyConfig,
    load_config,
    overridden,
    write_config,
)
from cmanip.configest import mpf_variant_options, proprioception_option
from cmanip.options import (
    backend_of,
    runner_options,
    setting_option,
    subcommand,
)
from cmanip.run import add_episode_options, override_episode, override_solver, solve
from diagrams.herb.settings import POLICIES
from experiments.closedloop_study import ClosedLoopSettings
from experiments.handplan_study import PARTS as HANDPLAN_PARTS
from experiments.latdespot_scenes import DEFAULT_POLICIES as LAT_DEFAULT_POLICIES
from experiments.latdespot_scenes import POLICIES as LAT_POLICIES
from experiments.latdespot_scenes import SCENES
from experiments.latdespot_study import CONTINUOUS_ROLLOUTS, OUTSIDE_MODES
from experiments.latdespot_study import PARTS as LATDESPOT_PARTS
from experiments.mpf_study import PARTS as MPF_PARTS
from experiments.visuotactile_study import PARTS as VISUOTACTILE_PARTS

MPF = MpfStudyConfig()
HANDPLAN = HandplanStudyConfig()
CLOSEDLOOP = ClosedLoopSettings()
VISUOTACTILE = VisuotactileStudyConfig()
LATDESPOT = LatDespotStudyConfig()


def register(commands) -> None:
    experiment = subcommand(commands, "experiment", "studies that reproduce the published "
                                                    "figures and tables")
    studies = experiment.add_subparsers(dest="study", required=True, metavar="STUDY")
    mpf = subcommand(studies, "mpf", "CPF vs MPF and the manifold representations "
                                     "(thesis sec. 4.3)")
    _config_option(mpf)
    setting_option(mpf, "--part", MPF.part, "which figure (all: every part into its own "
                                            "folder)", choices=[*MPF_PARTS, "all"])
    setting_option(mpf, "--trials", MPF.trials, "trials per condition", type=int)
    setting_option(mpf, "--seed", MPF.seed, "study seed; trial j is seeded from (seed, j)",
                   type=int)
    runner_options(mpf)
    setting_option(mpf, "--object", MPF.trial.object, "object name or path to a YAML")
    setting_option(mpf, "--sensors", MPF.trial.sensors,
                   "planar sensor layout (low, medium, high or a YAML path)")
    setting_option(mpf, "--push-distance", MPF.trial.push_distance_m, "hand travel (m)",
                   type=float)
    mpf.add_argument("--out", type=Path, required=True,
                     help="output directory (summary.json, figures, config.yaml)")
    mpf.add_argument("--no-progress", action="store_true", help="no progress bars")
    mpf.set_defaults(handler=_mpf)

    pushval = subcommand(studies, "pushval",
                         "planar pushing model vs Drake on 20 straight pushes")
    pushval.add_argument("--push-distance", type=float, default=0.15, help="hand travel (m)")
    runner_options(pushval)
    pushval.add_argument("--out", type=Path, required=True,
                         help="output directory (summary.json, push_validation.png, "
                              "trials.jsonl)")
    pushval.add_argument("--no-progress", action="store_true", help="no progress bars")
    pushval.set_defaults(handler=_pushval)

    handplan = subcommand(studies, "handplan", "QMDP vs point-based post-contact policies, "
                                               "pre-contact A*, sensor coverage (thesis ch. 6)")
    _config_option(handplan)
    setting_option(handplan, "--part", HANDPLAN.part, "which comparison",
                   choices=HANDPLAN_PARTS)
    setting_option(handplan, "--trials", HANDPLAN.study.trials,
                   "continuous-model trials per policy (discrete: twice as many)", type=int)
    setting_option(handplan, "--seed", HANDPLAN.study.seed, "master seed", type=int)
    setting_option(handplan, "--solve-seconds", HANDPLAN.study.solve_seconds,
                   "point-based solver budget (s)", type=float)
    setting_option(handplan, "--solve-trials", HANDPLAN.study.solve_trials,
                   "also stop the solver after this many search trials (reproducible "
                   "across machines)", type=int)
    setting_option(handplan, "--plan-seconds", HANDPLAN.study.precontact.time_limit_s,
                   "pre-contact search budget per belief (s)", type=float)
    handplan.add_argument("--search-until-contact", action="store_true",
                          help="pre-contact search ignores the 85 %% trust-region stop")
    setting_option(handplan, "--horizon", HANDPLAN.study.horizon, "post-contact steps",
                   type=int)
    handplan.add_argument("--problem", type=Path, default=None,
                          help="YAML of HandProblemSpec fields (trust region, cells, goal, "
                               "discount, samples per state; overrides on the thesis' "
                               "problem)")
    handplan.add_argument("--quick", action="store_true",
                          help="a small problem (coarse trust region, few samples) to try "
                               "it out; the options given still apply")
    handplan.add_argument("--out", type=Path, required=True,
                          help="output directory (summary.json, figures, config.yaml)")
    runner_options(handplan)
    handplan.add_argument("--no-progress", action="store_true", help="no progress bars")
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
    runner_options(closedloop)
    closedloop.add_argument("--out", type=Path, required=True,
                            help="output directory (summary.json, closedloop.png, "
                                 "config.yaml, trials.jsonl)")
    closedloop.set_defaults(handler=_closedloop)

    vt = subcommand(studies, "visuotactile",
                    "vision + touch smoothing vs EKF and vision (Yu and Rodriguez 2018)")
    _config_option(vt)
    setting_option(vt, "--part", VISUOTACTILE.part, "which comparison",
                   choices=[*VISUOTACTILE_PARTS, "all"])
    setting_option(vt, "--trials", VISUOTACTILE.study.trials,
                   "runs per condition (at least 2)", type=int)
    setting_option(vt, "--seed", VISUOTACTILE.study.seed, "master seed", type=int)
    setting_option(vt, "--noise-trials", VISUOTACTILE.study.noise_trials,
                   "training runs for the noise identification", type=int)
    setting_option(vt, "--rig", "the built-in pusher_slider.yaml", "rig YAML")
    runner_options(vt, resume=False)  # the simulated logs in OUT/logs are always reused
    vt.add_argument("--out", type=Path, required=True,
                    help="output directory (summary.json, figures, config.yaml, logs/)")
    vt.add_argument("--no-progress", action="store_true", help="no progress bars")
    vt.set_defaults(handler=_visuotactile)
    _register_latdespot(studies)
    _register_configest(studies)


def _register_configest(studies) -> None:
    from experiments.configest_study import ARMS, ConfigestSettings

    defaults = ConfigestSettings()
    ce = subcommand(studies, "configest", "thesis ch. 5: robot configuration estimation, "
                                          "CPF vs the MPF with implicit manifolds (Fig. 5.3)")
    _config_option(ce)
    ce.add_argument("--arm", default=argparse.SUPPRESS,
                    help=f"{', '.join(ARMS)}, all, or a path to an arm YAML (default: all)")
    setting_option(ce, "--trials", defaults.trials, "experiments per arm", type=int)
    setting_option(ce, "--seed", defaults.seed, "study seed", type=int)
    setting_option(ce, "--method", defaults.method, "projection root finder (gd: the "
                                                    "thesis' gradient descent)",
                   choices=("lm", "gd"))
    mpf_variant_options(ce, defaults)
    proprioception_option(ce, defaults)
    runner_options(ce)
    ce.add_argument("--out", type=Path, required=True,
                    help="output directory (summary.json, configest.png, config.yaml, "
                         "trials.jsonl)")
    ce.add_argument("--no-progress", action="store_true", help="no progress bars")
    ce.set_defaults(handler=_configest)


def _configest(args: argparse.Namespace) -> int:
    from experiments.configest_study import ARMS, ConfigestSettings, run_study
    from models.arms.spec import ArmSpec
    from models.arms.world import ArmWorld

    settings = overridden(load_config(ConfigestSettings, args.config), args, {
        "trials": "trials", "seed": "seed", "method": "method",
        "ball_radius": "ball_radius_rad", "constraints": "constraints",
        "dual_share": "dual_share", "metric": "metric", "dual_density": "dual_density",
        "dual_lift": "dual_lift", "proprioception": "proprioception"})
    if "arm" in vars(args):
        settings = replace(settings, arms=ARMS if args.arm == "all" else (args.arm,))
    for arm in settings.arms:  # a bad arm file (or link) fails before any trial runs
        ArmWorld(ArmSpec.load(arm))
    summary = run_study(settings, args.out, backend=backend_of(args), resume=args.resume,
                        progress=not args.no_progress)
    write_config(settings, args.out)
    for arm, filters in summary["arms"].items():
        print(f"{arm}:")
        for kind, entry in filters.items():
            if not isinstance(entry, dict):
                continue
            fail = entry.get("projection_failure_rate")
            extra = "" if fail is None else (
                f", projection failures {fail:.0%}; paired with the CPF "
                f"{entry['vs_cpf_rad_mean']:+.3f} +- {entry['vs_cpf_rad_mean_ci95']:.3f} rad")
            print(f"  {kind:13s} RMSE mean {entry['rmse_rad_mean']:.3f} "
                  f"+- {entry['rmse_rad_mean_ci95']:.3f} rad, final "
                  f"{entry['rmse_rad_final']:.3f} +- {entry['rmse_rad_final_ci95']:.3f} rad, "
                  f"{entry['update_ms_median']:.1f} ms/update{extra}")
    print("hypotheses:", json.dumps(summary["hypotheses"]))
    print(f"wrote {args.out}/summary.json, configest.png and config.yaml")
    return 0


def _register_latdespot(studies) -> None:
    lat = subcommand(studies, "latdespot", "thesis ch. 7: the hand-relative problem (7.3.3), "
                                           "the Lat-POMDP scenes (7.3.4), the bound (7.3.5)")
    _config_option(lat)
    rel = LATDESPOT.rel
    setting_option(lat, "--part", LATDESPOT.part, "which experiment", choices=LATDESPOT_PARTS)
    setting_option(lat, "--trials", rel.trials, "episodes per policy and model", type=int)
    setting_option(lat, "--seed", rel.seed, "the study's seed", type=int)
    setting_option(lat, "--horizon", rel.horizon, "steps per episode", type=int)
    setting_option(lat, "--problem", rel.problem, "the problem (built-in name or YAML path): "
                   "rel_ch7_contact, with the contact manifold's own states (beyond the "
                   "thesis), or rel_ch7, the thesis' grid")
    setting_option(lat, "--solve-seconds", rel.solve_seconds,
                   "point-based solver wall-time cap (s)", type=float)
    setting_option(lat, "--solve-trials", rel.solve_trials,
                   "point-based solver trial budget", type=int)
    setting_option(lat, "--despot-trials", rel.despot_trials,
                   "DESPOT trials per decision", type=int)
    setting_option(lat, "--despot-seconds", rel.despot_seconds,
                   "DESPOT wall-clock cap per decision (s)", type=float)
    setting_option(lat, "--continuous-despot-trials", rel.continuous_despot_trials,
                   "DESPOT trials per decision on the continuous model "
                   "(rel-despot-continuous)", type=int)
    setting_option(lat, "--continuous-rollout", rel.continuous_rollout,
                   "rel-despot-continuous's rollouts: Rel-QMDP on the discrete model from "
                   "each scenario's cell, or on the continuous model (slow)",
                   choices=list(CONTINUOUS_ROLLOUTS))
    setting_option(lat, "--continuous-outside", rel.continuous_outside,
                   "lat-despot-continuous's bounds for an object outside the trust region: "
                   "the discrete model's absorbing sentinel, or the steps back to the "
                   "region then the bounds there", choices=list(OUTSIDE_MODES))
    scenes = LATDESPOT.scenes
    setting_option(lat, "--scene", "all", "the scenes of parts scenes and bound (built-in "
                   f"name or YAML path, or all: {', '.join(scenes.scenes)})")
    setting_option(lat, "--policies", "all", "the policies of part scenes (all: "
                   f"{', '.join(scenes.policies)}; lat-despot-continuous by name, about a "
                   "second a decision)", nargs="+", choices=[*LAT_POLICIES, "all"])
    setting_option(lat, "--policy-trials", scenes.policy_trials,
                   "POLICY=N: fewer episodes of a costly policy than --trials (e.g. "
                   "rel-despot=50 lat-despot-pb=20)", nargs="+")
    setting_option(lat, "--lat-despot-trials", scenes.lat_despot_trials,
                   "DESPOT trials per Lat-DESPOT decision (0: the wall-clock cap alone)",
                   type=int)
    setting_option(lat, "--lat-despot-seconds", scenes.lat_despot_seconds,
                   "Lat-DESPOT's wall-clock cap per decision (s)", type=float)
    setting_option(lat, "--cache", scenes.cache_dir,
                   "where the lattice's IK table is kept")
    runner_options(lat)
    lat.add_argument("--no-progress", action="store_true", help="no progress bars")
    lat.add_argument("--out", type=Path, required=True,
                     help="output directory (summary.json, figures, config.yaml, "
                          "trials.jsonl, solved_rel.npz)")
    lat.set_defaults(handler=_latdespot)


def resolve_latdespot(args: argparse.Namespace) -> LatDespotStudyConfig:
    """The ch. 7 study's configuration: ``--config`` (or the defaults), then the options
    given."""
    config = load_config(LatDespotStudyConfig, args.config)
    rel = overridden(config.rel, args, {
        "trials": "trials", "seed": "seed", "horizon": "horizon", "problem": "problem",
        "solve_seconds": "solve_seconds", "solve_trials": "solve_trials",
        "despot_trials": "despot_trials", "despot_seconds": "despot_seconds",
        "continuous_despot_trials": "continuous_despot_trials",
        "continuous_rollout": "continuous_rollout",
        "continuous_outside": "continuous_outside"})
    scenes = overridden(config.scenes, args, {
        "lat_despot_seconds": "lat_despot_seconds", "cache_dir": "cache"})
    given = vars(args)
    if given.get("policy_trials") is not None:
        scenes = replace(scenes, policy_trials=tuple(given["policy_trials"]))
    if given.get("scene") is not None:
        scenes = replace(scenes, scenes=SCENES if given["scene"] == "all"
                         else (given["scene"],))
    if given.get("policies") is not None:  # all: the default set, whatever a --config says
        scenes = replace(scenes, policies=LAT_DEFAULT_POLICIES if "all" in given["policies"]
                         else tuple(given["policies"]))
    if given.get("lat_despot_trials") is not None:
        trials = given["lat_despot_trials"]
        scenes = replace(scenes, lat_despot_trials=trials if trials > 0 else None)
    return overridden(replace(config, rel=rel, scenes=scenes), args, {"part": "part"})


def _latdespot(args: argparse.Namespace) -> int:
    from experiments.latdespot_run import run_study
    from models.herb.scene import SceneSpec
    from planning.hand.discretization import HandProblemSpec

    config = resolve_latdespot(args)
    HandProblemSpec.load(config.rel.problem)  # a bad file fails before any solving
    if config.part != "rel":
        for scene in config.scenes.scenes:
            SceneSpec.load(scene)
    summary = run_study(config.part, config.rel, config.scenes, args.out,
                        backend=backend_of(args), resume=args.resume,
                        progress=not args.no_progress)
    write_config(config, args.out)
    for name, r in summary.get("rel", {}).items():
        success = ""
        if "success_rate" in r:
            lo, hi = r["success_rate_ci95"]
            success = f"success {r['success_rate']:.0%} [{lo:.0%}, {hi:.0%}]; "
        print(f"  {name:21s} value {r['discounted_value']:7.2f} +- "
              f"{r['discounted_value_ci95']:.2f} ({r['value_model']} model); "
              f"{success}planning median {r['planning_ms_median']:.2f} ms")
    for scene, entries in summary.get("scenes", {}).items():
        print(f"  {scene}:")
        for name, r in entries.items():
            lo, hi = r["success_rate_ci95"]
            print(f"    {name:14s} value {r['discounted_value']:7.2f} +- "
                  f"{r['discounted_value_ci95']:.2f}; success {r['success_rate']:.0%} "
                  f"[{lo:.0%}, {hi:.0%}]; infeasible {r['infeasible_rate']:.0%}; "
                  f"planning median {r['planning_ms_median']:.1f} ms, "
                  f"p99 {r['planning_ms_p99']:.1f} ms")
    for name, verdict in summary.get("hypotheses", {}).items():
        if verdict is not None:
            print(f"  {name}: {json.dumps(verdict.get('shown', verdict.get('holds')))}")
    if "bound" in summary:
        bound = summary["bound"]
        for scene, check in bound["scenes"].items():
            rel = ", ".join(f"{name} {e['discounted_value']:.2f} +- "
                            f"{e['discounted_value_ci95']:.2f} ({e['trials']})"
                            for name, e in check["rel_pomdp"].items())
            upper = ", ".join(f"{k} {v:.2f}" for k, v in check["rel_upper_bounds"].items())
            print(f"  bound, {scene}: best Lat {check['best_lat_policy']} "
                  f"{check['best_lat_value']:.2f}; on Rel-POMDP {rel}; upper bounds {upper}")
        verdict = ("holds" if bound["holds"] else "holds within the 95 % intervals"
                   if bound["holds_within_ci95"] else "VIOLATED")
        print(f"  bound of sec. 7.3.5 (Rel values above every Lat value): {verdict}; "
              f"below Rel-POMDP's upper bounds: {bound['below_upper_bounds']}")
    print(f"wrote {args.out}/summary.json, the figures and config.yaml")
    return 0


def _config_option(parser) -> None:
    parser.add_argument("--config", type=Path, default=None,
                        help="a YAML configuration (e.g. a study's DIR/config.yaml); the "
                             "options below override it")


def resolve_mpf(args: argparse.Namespace) -> MpfStudyConfig:
    """The MPF study's configuration: ``--config`` (or the defaults), then the options
    given; the object and sensor files are read once here, so a bad one fails before any
    trial runs."""
    from models.objects import ObjectSpec
    from models.planar.hand import PlanarSensorLayout

    config = load_config(MpfStudyConfig, args.config)
    trial = overridden(config.trial, args, {"object": "object", "sensors": "sensors",
                                            "push_distance": "push_distance_m"})
    config = overridden(replace(config, trial=trial), args,
                        {"part": "part", "trials": "trials", "seed": "seed"})
    ObjectSpec.load(config.trial.object)
    PlanarSensorLayout.load(config.trial.sensors)
    return config


def _mpf(args: argparse.Namespace) -> int:
    from experiments.mpf_study import run_study

    config = resolve_mpf(args)
    summary = run_study(config.part, config.trial, config.trials, config.seed, args.out,
                        backend=backend_of(args), resume=args.resume,
                        progress=not args.no_progress)
    write_config(config, args.out)
    parts = summary["parts"] if config.part == "all" else {config.part: summary}
    for name, part in parts.items():
        print(f"{name}:")
        for label, entry in part["filters"].items():
            fail = entry.get("sampling_failure_rate")
            extra = (f", sampling failures {fail:.0%} ("
                     f"{entry['sampling_failure_rate_correct_readings']:.0%} on correct readings)"
                     if fail is not None else "")
            print(f"  {label:28s} post-contact RMSE {entry['post_contact_rmse_cm']:.2f} cm, "
                  f"{entry['post_contact_rmse_deg']:.1f} deg{extra}")
    print(f"wrote {args.out}/summary.json, figures and config.yaml")
    return 0


def _pushval(args: argparse.Namespace) -> int:
    from experiments.push_validation import run_push_validation

    if not 0.0 < args.push_distance <= 0.4:
        raise ValueError(f"--push-distance {args.push_distance} m is outside (0, 0.4] m")
    s = run_push_validation(args.out, push_distance_m=args.push_distance,
                            backend=backend_of(args), resume=args.resume,
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


def resolve_handplan(args: argparse.Namespace) -> HandplanStudyConfig:
    """The hand-relative study's configuration: ``--config`` (or the defaults), then
    ``--problem``, then ``--quick``'s small problem, then the other options given."""
    from experiments.handplan_study import quick_settings
    from planning.hand.discretization import HandProblemSpec

    config = load_config(HandplanStudyConfig, args.config)
    study = config.study
    if args.problem is not None:
        study = replace(study, spec=HandProblemSpec.load(args.problem))
    if args.quick:
        study = quick_settings(study)
    given = vars(args)
    precontact = overridden(study.precontact, args, {"plan_seconds": "time_limit_s"})
    if args.search_until_contact:
        precontact = replace(precontact, trust_mass_stop=None)
    study = overridden(replace(study, precontact=precontact), args, {
        "trials": "trials", "seed": "seed", "solve_seconds": "solve_seconds",
        "solve_trials": "solve_trials", "horizon": "horizon"})
    return HandplanStudyConfig(given.get("part", config.part), study)


def _handplan(args: argparse.Namespace) -> int:
    from experiments.handplan_study import run_study

    config = resolve_handplan(args)
    if config.study.trials < 2:
        raise ValueError(f"--trials must be >= 2, got {config.study.trials}")
    summary = run_study(config.part, config.study, args.out, backend=backend_of(args),
                        resume=args.resume, progress=not args.no_progress)
    write_config(config, args.out)
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
    print(f"wrote {args.out}/summary.json, figures and config.yaml")
    return 0


def _closedloop(args: argparse.Namespace) -> int:
    from experiments.closedloop_study import run_closedloop_study

    config = resolve_closedloop(args)
    solution = solve(config.solver, config.cache_dir, progress=not args.no_progress)
    print(f"planning model ready ({len(solution.model.pomdp.states)} states); episodes "
          f"load it from {config.cache_dir}")
    summary = run_closedloop_study(config.study, config.solver, args.out,
                                   backend=backend_of(args), resume=args.resume,
                                   progress=not args.no_progress,
                                   cache_dir=Path(config.cache_dir))
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
    study = overridden(study, args, {"trials": "trials", "seed": "seed"})
    return ClosedLoopStudyConfig(study, override_solver(config.solver, args),
                                 given.get("cache", config.cache_dir))


def resolve_visuotactile(args: argparse.Namespace) -> VisuotactileStudyConfig:
    """The visuo-tactile study's configuration: ``--config`` (or the defaults), then the
    options given; the rig file is read once here."""
    config = load_config(VisuotactileStudyConfig, args.config)
    study = overridden(config.study, args, {"trials": "trials", "seed": "seed",
                                            "noise_trials": "noise_trials", "rig": "rig"})
    config = overridden(replace(config, study=study), args, {"part": "part"})
    config.study.load_rig()
    return config


def _visuotactile(args) -> int:
    from experiments.visuotactile_study import run_study

    config = resolve_visuotactile(args)
    settings = config.study
    if settings.trials < 2 or settings.noise_trials < 1:
        raise ValueError("--trials must be >= 2 and --noise-trials >= 1")
    summaries = run_study(config.part, settings, args.out, progress=not args.no_progress,
                          backend=backend_of(args))
    write_config(config, args.out)
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
    print(f"wrote {args.out}/summary.json, figures and config.yaml")
    return 0
