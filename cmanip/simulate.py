"""``cmanip simulate``: HERB pushes an object straight ahead in a scene."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cmanip.options import subcommand, wait_for_meshcat
from models.contact import SimulationConfig


def register(commands) -> None:
    sim = subcommand(commands, "simulate", "push an object straight ahead in a scene; "
                                           "writes replay.html, summary.json, tactile.png")
    sim.add_argument("--scene", default="empty", help="built-in scene name or path to a YAML")
    sim.add_argument("--object", default=None,
                     help="object name or path (default: the scene's object)")
    sim.add_argument("--push-distance", type=float, default=0.3, help="palm travel (m)")
    sim.add_argument("--hand-speed", type=float, default=0.05, help="palm speed (m/s)")
    sim.add_argument("--tactile", default="default", help="tactile layout name or path")
    sim.add_argument("--time-step", type=float, default=SimulationConfig().time_step_s,
                     help="plant time step (s)")
    sim.add_argument("--seed", type=int, default=0, help="seeds the tactile sensors' noise")
    sim.add_argument("--out", type=Path, required=True, help="output directory")
    sim.add_argument("--meshcat", action="store_true",
                     help="serve Meshcat live on localhost (prints the URL) and, from a "
                          "terminal, wait for Enter at the end")
    sim.add_argument("--no-progress", action="store_true", help="no progress bar")
    sim.set_defaults(handler=_simulate)


def _simulate(args: argparse.Namespace) -> int:
    from diagrams.herb.straight_push import InfeasiblePush, run_straight_push, write_outputs
    from diagrams.meshcat import local_meshcat
    from models.herb.scene import SceneSpec
    from models.herb.tactile import TactileLayout

    if not 0.0 < args.push_distance <= 2.0:
        raise ValueError(f"--push-distance {args.push_distance} m is outside (0, 2] m")
    if not 0.0 < args.hand_speed <= 1.0:
        raise ValueError(f"--hand-speed {args.hand_speed} m/s is outside (0, 1] m/s")
    scene = SceneSpec.load(args.scene, object_override=args.object)
    layout = TactileLayout.load(args.tactile)
    sim = SimulationConfig(args.time_step)
    meshcat = local_meshcat()
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
        wait_for_meshcat(meshcat.web_url())
    return 0
