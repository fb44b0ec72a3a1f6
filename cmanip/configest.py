"""``cmanip configest run``: the thesis' real-robot configuration-estimation experiment
(sec. 5.5) as one HERB episode in Drake: the arm, offset encoders, the tactile system,
the CPF and MPF-Ball side by side; ``replay.html`` shows MPF-Ball's ghost arms collapsing
onto the arm on touch."""

from __future__ import annotations

import argparse
from pathlib import Path

from cmanip.config import overridden
from cmanip.options import check_outlier_gate, setting_option, subcommand, wait_for_meshcat


def register(commands) -> None:
    from diagrams.herb.configest_episode import ConfigestEpisodeSettings

    defaults = ConfigestEpisodeSettings()
    group = subcommand(commands, "configest", "robot configuration estimation in the HERB "
                                              "diagram (thesis ch. 5)")
    actions = group.add_subparsers(dest="action", required=True, metavar="ACTION")
    run = subcommand(actions, "run", "one episode: HERB's arm touches a box; CPF and "
                                     "MPF-Ball estimate its configuration (sec. 5.5)")
    setting_option(run, "--arm", defaults.arm, "arm file (name or YAML path): scene, "
                                                "sensors, offsets, commanded trajectory")
    setting_option(run, "--particles", defaults.particles, "particles per estimator",
                   type=int)
    setting_option(run, "--dual-particles", defaults.dual_particles,
                   "MPF-Ball's dual particles n_d per contact update (of --particles)",
                   type=int)
    setting_option(run, "--mixing-rate", defaults.mixing_rate,
                   "MPF-Ball's mixing rate phi in [0, 1] (Alg. 4.2)", type=float)
    setting_option(run, "--process-noise", defaults.process_noise_radius_rad,
                   "both estimators' motion noise per update: the radius (rad) of a uniform "
                   "ball added to each commanded step", type=float)
    setting_option(run, "--tactile-error-rate", "the arm file's sensor_error_rate",
                   "the tactile system's error rate during contact", type=float)
    mpf_variant_options(run, defaults)
    proprioception_option(run, defaults)
    setting_option(run, "--outlier-gate", "none (the thesis)",
                   "both estimators' outlier gate: a reading with evidence log p(o | b+) "
                   "below this (< 0), which no dual explains, is propagated through "
                   "unweighed", type=float)
    setting_option(run, "--seed", defaults.seed, "seeds the offset, the sensor noise and "
                                                 "the estimators", type=int)
    run.add_argument("--out", type=Path, required=True,
                     help="output directory (summary.json, joint_error.png, replay.html)")
    run.add_argument("--meshcat", action="store_true",
                     help="also keep the live Meshcat (localhost) up after the episode")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(handler=_run)


def mpf_variant_options(parser, defaults) -> None:
    """``--ball-radius``, and ``--constraints``, ``--dual-share``, ``--metric``,
    ``--dual-density`` and ``--dual-lift``, the configuration MPF's variants beyond the
    thesis (defaults from ``defaults``, a settings dataclass with these fields)."""
    from estimation.configuration.history import DUAL_DENSITIES
    from estimation.configuration.lift import DUAL_LIFTS
    from estimation.configuration.manifold import METRICS
    from estimation.configuration.projection import CONSTRAINTS
    from estimation.particles.filters import DUAL_SHARES

    setting_option(parser, "--ball-radius", "three kernel bandwidths; with --dual-density "
                   "history the arm's offset_sd_rad", "MPF-Ball's r_b (rad; joint metric)",
                   type=float)
    setting_option(parser, "--constraints", defaults.constraints,
                   "what a projected dual satisfies (active: the lit sensors touch, eq. "
                   "5.1; full: also every other sensor clear, the body out of penetration)",
                   choices=CONSTRAINTS)
    setting_option(parser, "--dual-share", defaults.dual_share,
                   "the MPF's mass for its duals (fixed: phi, Alg. 4.2; density: phi scaled "
                   "by the posterior density the duals see; evidence: phi scaled by the share "
                   "of the reading the prior fails to explain)", choices=DUAL_SHARES)
    setting_option(parser, "--metric", defaults.metric,
                   "the metric of the projection's balls and steps (joint: joint space, "
                   "sec. 5.2; kernel: each joint in its kernel bandwidths)", choices=METRICS)
    setting_option(parser, "--dual-density", defaults.dual_density,
                   "how the MPF weighs its duals (kernel: the predicted particles' kernel "
                   "density, sec. 4.2.3; history: the exact density of every reading so "
                   "far, with joint-metric balls of the offset's sd)", choices=DUAL_DENSITIES)
    setting_option(parser, "--dual-lift", defaults.dual_lift,
                   "where the MPF's duals sit (surface: on the contact manifold, sec. 5.2; "
                   "normal: lifted along the contact normal to the commanded-side state the "
                   "dual density favours, on a grid of depths; normal-refined: the same, "
                   "then bisected around the grid's best depth)", choices=DUAL_LIFTS)


def proprioception_option(parser, defaults) -> None:
    """``--proprioception``: what every estimator takes from the encoders."""
    from estimation.configuration.proprioception import PROPRIOCEPTION

    setting_option(parser, "--proprioception", defaults.proprioception,
                   "what the estimators take from the encoders (first: their first reading, "
                   "the initial belief; steps: also each step's motion, which shows where a "
                   "contact stopped the arm)", choices=PROPRIOCEPTION)


def _run(args: argparse.Namespace) -> int:
    from diagrams.herb.configest_episode import (
        ConfigestEpisodeSettings,
        run_configest_episode,
    )
    from diagrams.meshcat import local_meshcat
    from models.arms.spec import ArmSpec

    check_outlier_gate(args)
    same = ("arm", "particles", "dual_particles", "mixing_rate", "seed", "tactile_error_rate",
            "constraints", "dual_share", "metric", "dual_density", "dual_lift", "proprioception")
    settings = overridden(ConfigestEpisodeSettings(), args, {
        **{key: key for key in same}, "outlier_gate": "outlier_log_evidence",
        "ball_radius": "ball_radius_rad",
        "process_noise": "process_noise_radius_rad"})
    spec = ArmSpec.load(settings.arm)  # a bad arm file fails before anything is built
    if spec.kind != "herb":
        raise ValueError(f"{spec.source}: the HERB episode needs a 'herb' arm, got "
                         f"{spec.kind!r}")
    meshcat = local_meshcat()
    if args.meshcat:
        print(f"Meshcat is live at {meshcat.web_url()}", flush=True)
    summary = run_configest_episode(settings, args.out, meshcat=meshcat,
                                    progress=not args.no_progress)
    for kind, entry in summary["estimators"].items():
        print(f"{kind:9s} joint error final {entry['joint_error_rad_final']:.3f} rad, mean "
              f"{entry['joint_error_rad_mean']:.3f} rad "
              f"({entry['contact_updates']} updates with contact)")
    print(f"encoders  joint error final {summary['encoder_error_rad_final']:.3f} rad")
    print(f"wrote {args.out}/summary.json, joint_error.png, replay.html")
    if args.meshcat:
        wait_for_meshcat(meshcat.web_url())
    return 0
