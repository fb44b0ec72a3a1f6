"""One closed-loop episode (thesis sec. 6.5, in simulation): place the object, build the
diagram of :mod:`diagrams.herb.closed_loop`, simulate until the episode ends.

An episode draws the object's true pose from the initial belief (hand frame), places it on
the table in front of the hand, and runs until the controller stops (its horizon, or no
feasible action), the object leaves the table or topples, or a time limit. A simulator
monitor (:class:`EpisodeWatch`) records the trace every 0.05 s and ends the simulation on
those events. Success is the thesis' rule: the object's centre is in the goal region when
the episode ends.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus
from tqdm import tqdm

from diagrams.herb.closed_loop import (
    ClosedLoopDiagram,
    build_closed_loop,
    controller_parts,
)
from diagrams.herb.controller import Decision
from diagrams.herb.metrics import summarise_episode
from diagrams.herb.settings import TOPPLED_RAD, EpisodeSettings
from estimation.hand.tracker import ParticleFilter
from estimation.particles.belief import ParticleBelief
from models.herb.scene import PlanarPose, SceneSpec
from models.herb.tactile import TactileLayout
from models.objects import ObjectSpec
from models.se2 import compose, inverse
from planning.hand.model import HandPOMDP, goal_region
from planning.hand.solution import HandSolution
from planning.lattice.contact import UnmodelledContact
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.planners import lattice_point

#: Where the lattice's IK table is kept by default (relative to the working directory).
DEFAULT_LATTICE_CACHE = Path("out/cache")
TRACE_PERIOD_S = 0.05
"""The trace's sampling period (s); the end conditions are checked at the same instants."""


@dataclass
class Episode:
    """What one episode produced: ``summary`` (JSON-ready), the trace over time (arrays
    keyed by name, one row per 0.05 s: ``time_s``, ``palm`` and ``object`` world poses,
    ``true_rel`` and the belief ``mean`` in the hand frame, ``rmse_m``, ``rmse_rad``,
    ``in_goal``, ``readings``), the belief at each decision (``time_s`` (K,),
    ``particles`` (K, N, 3) and ``true_rel`` (K, 3), hand frame) and the Meshcat
    recording (or ``None``)."""

    summary: dict
    trace: dict[str, np.ndarray]
    snapshots: dict[str, np.ndarray]
    html: str | None


class EpisodeWatch:
    """The simulator monitor of an episode: every :data:`TRACE_PERIOD_S` it records the
    trace and checks the end conditions; it ends the simulation (``ReachedTermination``)
    when the object has left the table or toppled, or when the controller has stopped and
    the executor has finished the last motion. ``stop`` says why (``time_limit`` until one
    of them happens)."""

    def __init__(self, loop: ClosedLoopDiagram, scene: SceneSpec, model: HandPOMDP,
                 bar: tqdm):
        self._loop, self._scene, self._model, self._bar = loop, scene, model, bar
        self._next_sample_s = TRACE_PERIOD_S
        self.stop = "time_limit"
        self.trace: dict[str, list] = {k: [] for k in (
            "time_s", "palm", "object", "true_rel", "mean", "rmse_m", "rmse_rad", "in_goal",
            "readings")}

    def __call__(self, root) -> EventStatus:
        # samples at k * 0.05 s, k >= 1 (the simulator's steps land on them: 5 ms plant
        # steps and 10/20 ms events); half a plant step of slack for rounding
        if root.get_time() < self._next_sample_s - 1e-6:
            return EventStatus.DidNothing()
        self._next_sample_s += TRACE_PERIOD_S
        loop = self._loop
        poses, tactile, controller = loop.poses, loop.tactile, loop.controller
        poses_context = poses.GetMyContextFromRoot(root)
        palm = poses.GetOutputPort("palm_pose").Eval(poses_context)
        obj = poses.GetOutputPort("object_pose").Eval(poses_context)
        belief = loop.estimator.GetOutputPort("belief").Eval(
            loop.estimator.GetMyContextFromRoot(root))
        rel = compose(inverse(palm), obj)
        rmse = belief.rmse(rel)
        for key, value in (("time_s", root.get_time()), ("palm", palm), ("object", obj),
                           ("true_rel", rel), ("mean", belief.mean()), ("rmse_m", rmse[0]),
                           ("rmse_rad", rmse[1]),
                           ("in_goal", bool(self._model.in_goal(rel[None])[0])),
                           ("readings", tactile.GetOutputPort("sensor_contact").Eval(
                               tactile.GetMyContextFromRoot(root)).copy())):
            self.trace[key].append(value)
        controller_context = controller.GetMyContextFromRoot(root)
        decisions = controller.decisions(controller_context)
        self._bar.update(len(decisions) - self._bar.n)
        if not self._scene.table.contains(obj[0], obj[1], 0.01):
            self.stop = "object_left_table"
        elif poses.GetOutputPort("object_tilt").Eval(poses_context)[0] > TOPPLED_RAD:
            self.stop = "object_toppled"
        elif controller.finished(controller_context) and self._last_motion_done(root,
                                                                                 decisions):
            self.stop = "no_feasible_action" if decisions[-1].action < 0 else "horizon"
        else:
            return EventStatus.DidNothing()
        return EventStatus.ReachedTermination(None, self.stop)

    def _last_motion_done(self, root, decisions: tuple[Decision, ...]) -> bool:
        """Has the executor finished (and settled after) the motion of the last decision,
        or, when that decision sent no action, the motion before it?"""
        executor = self._loop.executor
        context = executor.GetMyContextFromRoot(root)
        idle = executor.GetOutputPort("executor_state").Eval(context)[-1] > 0.5
        last_sent = len(decisions) if decisions[-1].action >= 0 else len(decisions) - 1
        return idle and executor.motion(context).decision >= last_sent


def run_episode(settings: EpisodeSettings, solution: HandSolution, *,
                meshcat: Meshcat | None = None, progress: bool = True,
                filter: ParticleFilter | None = None,
                cache_dir: Path | None = DEFAULT_LATTICE_CACHE) -> Episode:
    """Run one episode (see the module docstring).

    Args:
        settings: the episode.
        solution: the solved planning model (its object must be ``settings.object_name``).
        meshcat: draw and record there; ``None`` draws nothing.
        progress: show a progress bar over the decisions.
        filter: the estimator's filter, to share one contact manifold across episodes
            (:func:`~diagrams.herb.closed_loop.estimator_filter`; default: built here).
        cache_dir: where the ``lat-despot`` planner's lattice IK table is kept.

    Raises:
        InfeasibleStart: the hand's start pose is unreachable.
        ValueError: the settings and the model disagree.
    """
    model = solution.model
    world = model.world
    pushed = ObjectSpec.load(settings.object_name).name  # a name or a path
    if world.object_spec.name != pushed:
        raise ValueError(f"the planning model is for {world.object_spec.name!r}, the episode "
                         f"pushes {pushed!r}")
    rng = np.random.default_rng([settings.seed, 0])
    mean, std = np.array(settings.belief_mean), np.array(settings.belief_std)
    scene = SceneSpec.load(settings.scene, object_override=settings.object_name)
    start = scene.hand_start.as_array()
    true_rel = UnmodelledContact(scene).free_start(
        lambda n: world.sample_gaussian(mean, std, n, rng=rng))
    initial = ParticleBelief.uniform(world.sample_gaussian(mean, std, settings.particles,
                                                           rng=rng))
    layout = TactileLayout.load(settings.layout)
    parts = controller_parts(settings, solution, scene, cache_dir=cache_dir)
    scene = replace(scene, object_pose=PlanarPose(*compose(start, true_rel)))
    loop = build_closed_loop(settings, solution, scene, parts, initial, layout=layout,
                             meshcat=meshcat, filter=filter)
    plant, herb, visualizer = loop.plant, loop.herb, loop.visualizer
    context = loop.diagram.CreateDefaultContext()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context),
                       herb.robot_positions(plant, parts.q_start))
    simulator = Simulator(loop.diagram, context)
    if meshcat is not None:
        meshcat.SetProperty("/Grid", "visible", False)
        meshcat.SetCameraPose(camera_in_world=[start[0] + 0.75, start[1] + 0.45, 1.2],
                              target_in_world=[start[0] + 0.3, start[1], herb.table_top_z_m])
        visualizer.StartRecording(False)
    simulator.Initialize()

    actions = model.spec.action_vectors()
    longest = float(np.max(np.linalg.norm(actions[:, :2], axis=1)))
    limit_s = 1.0 + settings.horizon * (longest / settings.hand_speed_m_per_s + 0.6) + 30.0
    label = settings.policy if settings.planner == "hand" else settings.planner
    bar = tqdm(total=settings.horizon, desc=f"episode ({label})", unit="decision",
               disable=not progress, leave=False)
    watch = EpisodeWatch(loop, scene, model, bar)
    simulator.set_monitor(watch)
    wall = time.perf_counter()
    simulator.AdvanceTo(limit_s)
    wall_s = time.perf_counter() - wall
    bar.close()
    html = None
    if visualizer is not None:
        visualizer.StopRecording()
        visualizer.PublishRecording()
        html = meshcat.StaticHtml()
    arrays = {k: np.array(v) for k, v in watch.trace.items()}
    root = simulator.get_context()
    decisions = loop.controller.decisions(loop.controller.GetMyContextFromRoot(root))
    refused = loop.executor.motion(loop.executor.GetMyContextFromRoot(root)).refused
    summary = summarise_episode(settings, solution, arrays, decisions,
                                goal_region(world, model.spec), watch.stop, wall_s, refused)
    if parts.lattice is not None:
        summary["lattice"] = lattice_summary(parts.lattice, decisions)
    return Episode(summary, arrays, _snapshots(decisions, arrays), html)


def lattice_summary(lattice: ConfigurationLattice, decisions: tuple[Decision, ...]) -> dict:
    """How much of the lattice the episode evaluated (thesis Fig. 7.1), and the clearance
    (m, Drake's signed distance) of each executed edge: how close the arm passed to the
    clutter, the table or itself."""
    stats = lattice.stats()
    clearance = [lattice.clearance(lattice_point(lattice, palm_pose=d.palm_pose), d.action)
                 for d in decisions if d.action >= 0]
    return {"points": stats.points, "edges": stats.edges,
            "edges_evaluated": stats.edges_evaluated,
            "edge_fraction_evaluated": stats.edge_fraction,
            "edges_feasible": stats.edges_feasible,
            "executed_clearance_m": clearance,
            "executed_clearance_min_m": min(clearance) if clearance else None}


def _snapshots(decisions: tuple[Decision, ...],
               trace: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    times = np.array([d.time_s for d in decisions])
    nearest = np.searchsorted(trace["time_s"], times).clip(0, len(trace["time_s"]) - 1)
    return {"time_s": times,
            "particles": np.array([np.asarray(d.belief.states) for d in decisions]),
            "true_rel": trace["true_rel"][nearest]}
