"""``cmanip push``: the pusher-slider rig of Yu and Rodriguez (ICRA 2018), vision plus touch.

    push simulate   run a pushing procedure in Drake and write its sensor log (CSV);
                    ``--html`` also writes the Meshcat replay with the estimate drawn.
    push estimate   run the estimator on any log (simulated or from a real robot).

Its study is ``experiment visuotactile`` and its bench ``bench visuotactile``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cmanip.options import subcommand


def register(commands) -> None:
    push = subcommand(commands, "push", "the pusher-slider rig: simulate a procedure into a "
                                        "sensor log, estimate any log")
    kinds = push.add_subparsers(dest="push", required=True, metavar="ACTION")
    sim = subcommand(kinds, "simulate", "run a pushing procedure; write the sensor log")
    sim.add_argument("--object", default="rect1", help="object name or path")
    sim.add_argument("--surface", default=None,
                     help="support surface (default: the rig file's)")
    sim.add_argument("--procedure", default="standard", choices=["standard", "random"],
                     help="the paper's standard strokes, or random ones")
    sim.add_argument("--strokes", type=int, default=8, help="strokes of a random procedure")
    sim.add_argument("--rig", type=Path, default=None,
                     help="rig YAML (default: the built-in pusher_slider.yaml)")
    sim.add_argument("--seed", type=int, default=0, help="seeds the sensors and procedure")
    sim.add_argument("--out", type=Path, required=True, help="the log (.csv) to write")
    sim.add_argument("--html", type=Path, default=None,
                     help="also write a Meshcat replay (true object, camera pose, estimate)")
    sim.add_argument("--noise", type=Path, default=None,
                     help="noise.json for the estimator drawn in the replay (default: the "
                          "built-in noise model)")
    sim.set_defaults(handler=_simulate)

    est = subcommand(kinds, "estimate", "run the estimator on a log")
    est.add_argument("log", type=Path, help="a push log (CSV, see models/pusher/log.py)")
    est.add_argument("--object", default=None,
                     help="object name or path (default: the log's 'object' header)")
    est.add_argument("--noise", type=Path, default=None,
                     help="noise.json from 'experiment visuotactile --part noise' "
                          "(default: identified from this log's ground truth)")
    est.add_argument("--history", type=int, default=200, help="smoothing window (steps)")
    est.add_argument("--paper", action="store_true",
                     help="the paper's pooled stationary prior instead of the recommended "
                          "contact-aware one")
    est.add_argument("--out", type=Path, default=None, help="estimates CSV to write")
    est.set_defaults(handler=_estimate)


def _simulate(args) -> int:
    from diagrams.meshcat import local_meshcat
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
    meshcat = local_meshcat() if args.html else None
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
