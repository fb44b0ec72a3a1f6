"""``cmanip simulate``: push the scene's object straight ahead with HERB's hand.

The hand's path is planned the way the planners move it (planar palm poses every 1 cm,
turned into arm configurations by :class:`~models.herb.kinematics.PlanarHandIK`), timed at a
nominal hand speed within the joint velocity limits, and tracked in the hydroelastic
simulation. Outputs: ``replay.html`` (Meshcat recording, self-contained), ``summary.json``
and ``tactile.png`` (per-patch force and binary contact over time).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from pydrake.geometry import Meshcat  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.trajectories import PiecewisePolynomial  # noqa: E402
from tqdm import tqdm  # noqa: E402

from diagrams.herb.station import HerbSimulation, build_herb_simulation  # noqa: E402
from models.contact import SimulationConfig  # noqa: E402
from models.herb.kinematics import PlanarHandIK, straight_push_path, time_parameterize  # noqa: E402
from models.herb.scene import SceneSpec  # noqa: E402
from models.herb.tactile import TactileLayout, TactileNoise  # noqa: E402
from models.pose import transform_to_planar  # noqa: E402

SETTLE_S = 0.3  # still time before and after the push (s)


class InfeasiblePush(RuntimeError):
    """The requested push cannot be executed (IK reports an unreachable or colliding pose)."""


@dataclass
class PushOutcome:
    """Everything one straight push produced."""

    summary: dict
    times_s: np.ndarray
    patch_names: tuple[str, ...]
    contact: np.ndarray  # (T, P) readings (0/1)
    force_n: np.ndarray  # (T, P)
    html: str | None


def plan_push(scene: SceneSpec, push_distance_m: float, hand_speed_m_per_s: float,
              *, seed: int) -> tuple[PiecewisePolynomial, PlanarHandIK, np.ndarray]:
    """Plan the arm trajectory of a straight push from the scene's hand start.

    Returns:
        (trajectory of the 7 arm joints, the IK object, (N, 3) planned palm poses).

    Raises:
        InfeasiblePush: when the start or any pose along the push is infeasible.
    """
    ik = PlanarHandIK(scene)
    start = scene.hand_start.as_array()
    first = ik.solve_multistart(start, rng=np.random.default_rng(seed))
    if not first.feasible:
        raise InfeasiblePush(f"start pose {np.round(start, 3).tolist()}: {first.reason}")
    path = straight_push_path(ik, start, push_distance_m, first.q)
    if not path.feasible:
        raise InfeasiblePush(path.reason)
    times = time_parameterize(path.q, path.poses, hand_speed_m_per_s=hand_speed_m_per_s,
                              velocity_limits=ik.velocity_limits)
    times = np.concatenate([[0.0], times + SETTLE_S, [times[-1] + 2 * SETTLE_S]])
    knots = np.vstack([path.q[:1], path.q, path.q[-1:]]).T
    zeros = np.zeros(knots.shape[0])
    trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(times, knots, zeros,
                                                                         zeros)
    return trajectory, ik, path.poses


def run_straight_push(
    scene: SceneSpec,
    push_distance_m: float,
    *,
    layout: TactileLayout,
    sim: SimulationConfig = SimulationConfig(),
    noise: TactileNoise = TactileNoise(),
    hand_speed_m_per_s: float = 0.05,
    seed: int = 0,
    meshcat: Meshcat | None = None,
    progress: bool = True,
) -> PushOutcome:
    """Plan and simulate one straight push; see the module docstring.

    Args:
        scene: the scene (its hand start is the push's start; theta its direction).
        push_distance_m: how far the palm travels (m).
        layout: tactile patch layout.
        sim: time step and contact approximation.
        noise: tactile noise model.
        hand_speed_m_per_s: nominal palm speed (m/s).
        seed: seeds the IK multistart and the tactile noise.
        meshcat: record (and show live) in this Meshcat; ``None`` draws nothing.
        progress: show a progress bar.

    Raises:
        InfeasiblePush: the push cannot be executed.
    """
    if push_distance_m <= 0:
        raise ValueError(f"push distance must be > 0 m, got {push_distance_m}")
    trajectory, ik, poses = plan_push(scene, push_distance_m, hand_speed_m_per_s, seed=seed)
    simulation = build_herb_simulation(scene, trajectory, layout=layout, sim=sim, noise=noise,
                                       seed=seed, meshcat=meshcat)
    context = simulation.initial_context(trajectory.value(0.0).ravel())
    simulator = Simulator(simulation.diagram, context)
    simulator.set_target_realtime_rate(0.0)
    if meshcat is not None:
        hand = scene.hand_start
        meshcat.SetCameraPose(camera_in_world=[hand.x + 0.9, hand.y + 1.0, 1.5],
                              target_in_world=[hand.x + 0.2, hand.y, scene.table.top_height_m])
    if simulation.visualizer is not None:
        simulation.visualizer.StartRecording(False)
    simulator.Initialize()
    duration = trajectory.end_time()
    chunk = 0.1
    wall_start = time.perf_counter()
    steps = np.arange(chunk, duration + chunk / 2, chunk)
    for t in tqdm(steps, desc="simulating", unit="0.1 s", disable=not progress, leave=False):
        simulator.AdvanceTo(min(t, duration))
    wall_s = time.perf_counter() - wall_start
    html = None
    if simulation.visualizer is not None:
        simulation.visualizer.StopRecording()
        simulation.visualizer.PublishRecording()
        html = meshcat.StaticHtml()
    return _outcome(simulation, simulator.get_context(), scene, push_distance_m, sim,
                    hand_speed_m_per_s, seed, duration, wall_s, poses, html)


def _outcome(simulation: HerbSimulation, context, scene, push_distance_m, sim, speed, seed,
             duration, wall_s, poses, html) -> PushOutcome:
    plant, world = simulation.plant, simulation.world
    plant_context = plant.GetMyContextFromRoot(context)
    initial = transform_to_planar(world.X_W_object_initial())
    final = transform_to_planar(plant.EvalBodyPoseInWorld(plant_context, world.object_body))
    palm = world.hand.palm_frame.CalcPoseInWorld(plant_context)
    commanded = world.X_W_palm(poses[-1])
    contact_log = simulation.contact_log.FindLog(context)
    force_log = simulation.force_log.FindLog(context)
    contact = contact_log.data().T
    names = simulation.tactile.patch_names
    summary = {
        "scene": scene.name,
        "object": scene.object.name,
        "push_distance_m": push_distance_m,
        "hand_speed_m_per_s": speed,
        "time_step_s": sim.time_step_s,
        "contact_approximation": sim.contact_approximation,
        "seed": seed,
        "sim_time_s": duration,
        "wall_time_s": wall_s,
        "real_time_factor": duration / wall_s,
        "object_initial_pose": initial.tolist(),
        "object_final_pose": final.tolist(),
        "object_displacement_m": float(np.linalg.norm(final[:2] - initial[:2])),
        "palm_final_error_m": float(np.linalg.norm(palm.translation() - commanded.translation())),
        "tactile_period_s": simulation.tactile.period_s,
        "contact_counts": {n: int(c) for n, c in zip(names, contact.sum(axis=0), strict=True)},
    }
    return PushOutcome(summary, contact_log.sample_times(), names, contact, force_log.data().T,
                       html)


def write_outputs(outcome: PushOutcome, out_dir: Path) -> None:
    """Write ``summary.json``, ``tactile.png`` and (when recorded) ``replay.html``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "summary.json").write_text(json.dumps(outcome.summary, indent=2) + "\n")
    if outcome.html is not None:
        (out_dir / "replay.html").write_text(outcome.html)
    plot_tactile(outcome, out_dir / "tactile.png")


def plot_tactile(outcome: PushOutcome, path: Path) -> None:
    """Force per patch over time (top) and the binary readings as a raster (bottom)."""
    fig, (ax_force, ax_contact) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True,
                                               gridspec_kw={"height_ratios": [1, 1.2]})
    touched = outcome.force_n.max(axis=0) > 0.5
    for i, name in enumerate(outcome.patch_names):
        if touched[i]:
            ax_force.plot(outcome.times_s, outcome.force_n[:, i], label=name)
    ax_force.set_ylabel("patch force (N)")
    ax_force.set_title(f"{outcome.summary['scene']}: {outcome.summary['object']} pushed "
                       f"{outcome.summary['push_distance_m']:.2f} m")
    if touched.any():
        ax_force.legend(loc="upper left", fontsize=8, ncol=2)
    extent = (outcome.times_s[0], outcome.times_s[-1], len(outcome.patch_names) - 0.5, -0.5)
    ax_contact.imshow(outcome.contact.T, aspect="auto", interpolation="nearest", cmap="Greys",
                      extent=extent, vmin=0, vmax=1)
    ax_contact.set_yticks(range(len(outcome.patch_names)), outcome.patch_names, fontsize=7)
    ax_contact.set_xlabel("time (s)")
    ax_contact.set_ylabel("contact reading (black = contact)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
