"""``cmanip`` subcommands for seed 003's pusher-slider (vision plus touch).

    push simulate   run a pushing procedure in Drake and write its sensor log (CSV);
                    ``--html`` also writes the Meshcat replay with the estimate drawn.
    push estimate   run the estimator on any log (simulated or from a real robot).
    experiment visuotactile   the study (:mod:`experiments.visuotactile_study`).
    bench visuotactile        the smoother's timing (:mod:`experiments.visuotactile_bench`).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HISTORY_CHOICES = (1, 100, 200, 1000)


def add_commands(commands, studies, bench_kinds) -> None:
    """Register the subcommands on the parsers of :mod:`cmanip.cli`."""
    push = commands.add_parser("push", help="seed 003's pusher-slider: simulate, estimate")
    kinds = push.add_subparsers(dest="push", required=True)
    sim = kinds.add_parser("simulate", help="run a pushing procedure; write the sensor log")
    sim.add_argument("--object", default="rect1", help="object name or path")
    sim.add_argument("--surface", default=None,
                     help="support surface (the rig's; default plywood)")
    sim.add_argument("--procedure", default="standard", choices=["standard", "random"])
    sim.add_argument("--strokes", type=int, default=8, help="strokes of a random procedure")
    sim.add_argument("--rig", type=Path, default=None, help="rig YAML (default: built-in)")
    sim.add_argument("--seed", type=int, default=0)
    sim.add_argument("--out", type=Path, required=True, help="the log (.csv) to write")
    sim.add_argument("--html", type=Path, default=None,
                     help="also write a Meshcat replay (true object, camera pose, estimate)")
    sim.add_argument("--noise", type=Path, default=None,
                     help="noise.json for the estimator drawn in the replay")

    est = kinds.add_parser("estimate", help="run the estimator on a log")
    est.add_argument("log", type=Path)
    est.add_argument("--object", default=None,
                     help="object name or path (default: the log's 'object' header)")
    est.add_argument("--noise", type=Path, default=None,
                     help="noise.json from 'experiment visuotactile --part noise' "
                          "(default: identified from this log's ground truth)")
    est.add_argument("--history", type=int, default=200)
    est.add_argument("--paper", action="store_true",
                     help="seed 003's pooled stationary prior instead of the recommended "
                          "contact-aware one")
    est.add_argument("--out", type=Path, default=None, help="estimates CSV to write")

    study = studies.add_parser("visuotactile",
                               help="vision + touch smoothing vs EKF and vision (seed 003)")
    study.add_argument("--part", default="methods",
                       choices=["noise", "methods", "shapes", "surfaces", "costs", "timing",
                                "all"])
    study.add_argument("--trials", type=int, default=10)
    study.add_argument("--seed", type=int, default=0)
    study.add_argument("--noise-trials", type=int, default=3,
                       help="training runs for the noise identification")
    study.add_argument("--rig", type=Path, default=None)
    study.add_argument("--out", type=Path, required=True)
    study.add_argument("--no-progress", action="store_true")

    bench = bench_kinds.add_parser("visuotactile", help="smoother update and relinearisation")
    bench.add_argument("--log", type=Path, default=None, help="time on this log")
    bench.add_argument("--object", default="rect1", help="the log's object")
    bench.add_argument("--seed", type=int, default=0)
    bench.add_argument("--json", type=Path, default=None)


def run(args: argparse.Namespace) -> int | None:
    """Handle a command of this module; ``None`` if it is not one."""
    if args.command == "push":
        return _simulate(args) if args.push == "simulate" else _estimate(args)
    if args.command == "experiment" and args.study == "visuotactile":
        return _study(args)
    if args.command == "bench" and args.bench == "visuotactile":
        from experiments.visuotactile_bench import run_visuotactile_bench

        report = run_visuotactile_bench(args.log, args.seed, args.object)
        if args.json:
            args.json.write_text(json.dumps(report, indent=2) + "\n")
        return 0
    return None


def _simulate(args) -> int:
    from pydrake.geometry import Meshcat

    from diagrams.pusher.simulation import simulate_push
    from estimation.pushing.noise import PushingNoise
    from models.objects import ObjectSpec
    from models.pusher.procedure import random_procedure, standard_procedure
    from models.pusher.rig import PusherSliderRig

    rig = PusherSliderRig.load(args.rig) if args.rig else PusherSliderRig.load()
    if args.surface:
        rig = rig.with_surface(args.surface)
    spec = ObjectSpec.load(args.object)
    procedure = (standard_procedure() if args.procedure == "standard"
                 else random_procedure(np.random.default_rng(args.seed), args.strokes))
    meshcat = Meshcat() if args.html else None
    noise = None
    if args.html:
        noise = PushingNoise.load(args.noise) if args.noise else PushingNoise()
    run = simulate_push(rig, spec, procedure, seed=args.seed, object_name=args.object,
                        estimator_noise=noise, meshcat=meshcat, progress=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    run.log.write(args.out)
    print(f"wrote {args.out}: {len(run.log)} rows, {run.log.t[-1]:.1f} s; a rod in contact "
          f"{run.contact_fraction:.0%} of the time, tag hidden in {run.occluded_fraction:.0%} "
          "of the camera frames")
    if meshcat is not None:
        args.html.parent.mkdir(parents=True, exist_ok=True)
        args.html.write_text(meshcat.StaticHtml())
        print(f"wrote {args.html} (red: the estimate, green: the camera's pose)")
    return 0


def _estimate(args) -> int:
    from estimation.pushing.inputs import PushingSteps, rmse
    from estimation.pushing.noise import PushingNoise, identify_from_runs
    from estimation.pushing.smoother import (
        SmootherSettings,
        VisuoTactileSmoother,
        recommended_settings,
    )
    from models.objects import ObjectSpec
    from models.pusher.log import PushLog

    log = PushLog.read(args.log)
    spec = ObjectSpec.load(args.object or log.object_name)
    polygon = spec.footprint()
    steps = PushingSteps.from_log(log)
    has_truth = bool(np.all(np.isfinite(steps.truth)))
    if args.noise:
        noise = PushingNoise.load(args.noise)
    elif has_truth:
        noise, _, _ = identify_from_runs([steps], polygon)
        print("noise identified from this log's ground truth (pass --noise to use a model "
              "identified elsewhere)")
    else:
        raise ValueError(f"{args.log} has no ground truth to identify the noise from; "
                         "pass --noise noise.json")
    settings = (SmootherSettings(history=args.history) if args.paper
                else recommended_settings(args.history))
    smoother = VisuoTactileSmoother(polygon, noise, settings, rod_radius_m=steps.rod_radius_m)
    estimates = smoother.run(steps)
    updates = np.array(smoother.update_seconds) * 1e3
    print(f"{len(steps)} steps; update mean {updates.mean():.3f} ms, max {updates.max():.1f} ms")
    if has_truth:
        mm, deg = rmse(estimates, steps.truth)
        print(f"RMSE against the log's ground truth: {mm:.1f} mm, {deg:.2f} deg")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        np.savetxt(args.out, np.column_stack([steps.t, estimates]), delimiter=",",
                   header="t_s,x_m,y_m,theta_rad", comments="", fmt="%.9g")
        print(f"wrote {args.out}")
    return 0


def _study(args) -> int:
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
