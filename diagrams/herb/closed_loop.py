"""The closed loop: HERB pushes an object into a goal region in front of its palm by touch,
in one Drake diagram (thesis sec. 6.5, in simulation). This module wires it;
:mod:`diagrams.herb.episode` runs an episode on it.

::

    plant --contact results--> TactileSensor --sensor_contact--> HandEstimator --belief-->
      ^                                                              ^           HandController
      |                        PlanarPoses --palm_pose---------------+                |
      +--arm desired state-- ActionExecutor <--command-----------------------------------+
                                   +--executor_state (idle, commanded pose, q)--> controller

Timing: the estimator checks every 10 ms and updates once the palm has travelled 5 mm; the
controller checks every 20 ms and decides when the executor is idle; the executor checks on
the same period, half a period later, so it sees the decision made at the check before.
Every system's state (the belief, the planner's memory and decisions, the current motion)
is an immutable value in the Context; the costly immutable cores (the filter and its
contact manifold, the solved policy, the IK) are members of the systems.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder

from diagrams.belief_drawing import BeliefDrawer
from diagrams.herb.controller import HandController
from diagrams.herb.estimator import HandEstimator
from diagrams.herb.executor import ActionExecutor
from diagrams.herb.lattice_drawing import LatticeDrawer
from diagrams.herb.poses import PlanarPoses
from diagrams.herb.settings import EpisodeSettings
from diagrams.herb.station import add_herb_plant, add_meshcat
from diagrams.tactile_sensor import TactileSensor
from estimation.hand.manifolds import AnalyticManifold
from estimation.hand.tracker import ParticleFilter
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from models.contact import SimulationConfig
from models.herb.kinematics import PlanarHandIK
from models.herb.motion import HandMotionPlanner, MotionPlanner
from models.herb.scene import SceneSpec
from models.herb.tactile import SensorGroups, TactileLayout
from models.herb.world import HerbWorld
from planning.hand.model import goal_region
from planning.hand.planner import HandPlanner, ThesisHandPlanner
from planning.hand.solution import HandSolution
from planning.lattice.contact import UnmodelledContact
from planning.lattice.grid import LatticeSpec
from planning.lattice.ik_table import load_ik_table
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.motion import LatticeMotion
from planning.lattice.planners import LatDespotPlanner
from planning.lattice.pomdp import LatticePOMDP
from planning.pomdp.despot import DespotSettings
from planning.protocols import Planner


def estimator_filter(kind: str, world, outlier_log_evidence: float | None = None
                     ) -> ParticleFilter:
    """The estimator's filter: the CPF, or the MPF on the analytic contact manifold (built
    here, about 10 s for the small box at the thesis' 1.15 deg; pass the result to several
    episodes to build it once), with the outlier gate ``outlier_log_evidence`` (None: none,
    the thesis)."""
    return make_filter(kind, world, AnalyticManifold(world) if kind == "mpf" else None,
                       outlier_log_evidence=outlier_log_evidence)


@dataclass
class ClosedLoopDiagram:
    """The built diagram and handles to its systems (``visualizer`` is ``None`` without
    Meshcat)."""

    diagram: Diagram
    plant: MultibodyPlant
    herb: HerbWorld
    tactile: TactileSensor
    poses: PlanarPoses
    estimator: HandEstimator
    controller: HandController
    executor: ActionExecutor
    visualizer: MeshcatVisualizer | None


@dataclass
class ControllerParts:
    """What the controller and executor run: the planner, the motion planner of actions,
    the arm's start (7,) rad (the palm at the scene's hand start), and the lattice (for the
    ``lat-despot`` planner, else None)."""

    planner: Planner
    motion: MotionPlanner
    q_start: np.ndarray
    lattice: ConfigurationLattice | None = None


class InfeasibleStart(RuntimeError):
    """The hand's start pose cannot be reached (IK)."""


def controller_parts(settings: EpisodeSettings, solution: HandSolution, scene: SceneSpec, *,
                     cache_dir: Path | None = None) -> ControllerParts:
    """The planner of ``settings.planner`` for ``scene`` (see
    :class:`~diagrams.herb.settings.EpisodeSettings`). For ``lat-despot``, the scene's
    lattice at the model's step (its IK table from ``cache_dir``, solved there when
    missing) and Lat-POMDP on the solution's hand-relative model; the arm starts at the
    lattice's start configuration.

    Raises:
        InfeasibleStart: the hand's start pose is unreachable.
    """
    model = solution.model
    start = scene.hand_start.as_array()
    if settings.planner == "lat-despot":
        spec = LatticeSpec(start=tuple(float(v) for v in start), resolution_m=model.spec.step_m)
        try:
            table = load_ik_table(scene, spec, cache_dir=cache_dir, progress=False)
        except ValueError as err:
            raise InfeasibleStart(str(err)) from err
        lattice = ConfigurationLattice(scene, table, model.spec.action_vectors())
        pomdp = LatticePOMDP(model, lattice, UnmodelledContact(scene),
                             inner=settings.lat_despot_model,
                             outside=settings.lat_despot_outside)
        planner = LatDespotPlanner(pomdp, DespotSettings(
            max_trials=settings.lat_despot_trials, seconds=settings.lat_despot_seconds))
        return ControllerParts(planner, LatticeMotion(lattice), table.q[spec.start_point],
                               lattice)
    ik = PlanarHandIK(scene, posture_weight=settings.posture_weight)
    first = ik.solve_multistart(start, rng=np.random.default_rng([settings.seed, 1]))
    if not first.feasible:
        raise InfeasibleStart(f"hand start {np.round(start, 3).tolist()}: {first.reason}")
    planner_type = HandPlanner if settings.planner_belief == "estimator" else ThesisHandPlanner
    planner = planner_type(model, solution.policies[settings.policy], settings.precontact)
    return ControllerParts(planner, HandMotionPlanner(ik), first.q)


def build_closed_loop(settings: EpisodeSettings, solution: HandSolution, scene: SceneSpec,
                      parts: ControllerParts, initial: ParticleBelief, *,
                      layout: TactileLayout, meshcat: Meshcat | None = None,
                      filter: ParticleFilter | None = None) -> ClosedLoopDiagram:
    """Wire the diagram of the module docstring.

    Args:
        settings: the episode.
        solution: the solved planning model.
        scene: the scene with the object already placed.
        parts: the planner, the motion planner and the arm's start
            (:func:`controller_parts`).
        initial: the estimator's initial belief (hand frame).
        layout: the Drake tactile layout.
        meshcat: draw there (``None``: no drawing).
        filter: the estimator's filter (default: :func:`estimator_filter` of
            ``settings.estimator``).
    """
    model, world = solution.model, solution.model.world
    motion = parts.motion
    builder = DiagramBuilder()
    sim = SimulationConfig(time_step_s=settings.time_step_s)
    plant, scene_graph, herb = add_herb_plant(builder, scene, layout=layout, sim=sim)
    groups = SensorGroups()
    if len(groups.names) != world.sensor_count:
        raise ValueError(f"{len(groups.names)} pooled sensors, but the planning model has "
                         f"{world.sensor_count}")
    tactile = builder.AddSystem(TactileSensor(layout, herb.hand.patch_geometry,
                                              noise=settings.noise, seed=settings.seed,
                                              groups=groups))
    builder.Connect(plant.get_contact_results_output_port(), tactile.get_input_port())
    poses = builder.AddSystem(PlanarPoses(plant, herb))
    builder.Connect(plant.get_body_poses_output_port(), poses.get_input_port())
    filter = filter or estimator_filter(settings.estimator, world,
                                        settings.estimator_outlier_log_evidence)
    estimator = builder.AddSystem(HandEstimator(
        filter, initial, world.sensor_count, seed=settings.seed, travel_m=settings.travel_m))
    builder.Connect(tactile.GetOutputPort("sensor_contact"),
                    estimator.GetInputPort("sensor_contact"))
    builder.Connect(poses.GetOutputPort("palm_pose"), estimator.GetInputPort("palm_pose"))
    actions = model.spec.action_vectors()
    controller = builder.AddSystem(HandController(
        parts.planner, motion, actions, initial, world.sensor_count, horizon=settings.horizon,
        on_infeasible=settings.on_infeasible, seed=settings.seed))
    executor = builder.AddSystem(ActionExecutor(motion, actions, scene.hand_start.as_array(),
                                                parts.q_start,
                                                hand_speed_m_per_s=settings.hand_speed_m_per_s))
    builder.Connect(estimator.GetOutputPort("belief"), controller.GetInputPort("belief"))
    builder.Connect(estimator.GetOutputPort("contact_seen"),
                    controller.GetInputPort("contact_seen"))
    builder.Connect(executor.GetOutputPort("executor_state"),
                    controller.GetInputPort("executor_state"))
    builder.Connect(tactile.GetOutputPort("sensor_contact"),
                    controller.GetInputPort("sensor_contact"))
    builder.Connect(controller.GetOutputPort("command"), executor.GetInputPort("command"))
    builder.Connect(executor.GetOutputPort("arm_desired_state"),
                    plant.get_desired_state_input_port(herb.wam))
    visualizer = None
    if meshcat is not None:
        visualizer = add_meshcat(builder, plant, scene_graph, meshcat)
        drawer = builder.AddSystem(BeliefDrawer(
            meshcat, world.shape.vertices[0][world.shape.valid[0]],
            goal_region(world, model.spec), _sensor_points(world), initial,
            height_m=herb.table_top_z_m + scene.object.height_m + 0.01,
            object_rgba=scene.object.rgba))
        builder.Connect(estimator.GetOutputPort("belief"), drawer.GetInputPort("belief"))
        builder.Connect(poses.GetOutputPort("palm_pose"), drawer.GetInputPort("palm_pose"))
        builder.Connect(tactile.GetOutputPort("sensor_contact"),
                        drawer.GetInputPort("sensor_contact"))
        if parts.lattice is not None:
            lattice_drawer = builder.AddSystem(LatticeDrawer(
                meshcat, parts.lattice, height_m=herb.table_top_z_m + 0.003))
            builder.Connect(executor.GetOutputPort("executor_state"),
                            lattice_drawer.GetInputPort("executor_state"))
    return ClosedLoopDiagram(builder.Build(), plant, herb, tactile, poses, estimator,
                             controller, executor, visualizer)


def _sensor_points(world) -> np.ndarray:
    """(S, 2) the centre of each planar sensor's segments (hand frame)."""
    segments, owner = world.hand.sensor_segments, world.hand.sensor_of_segment
    middles = segments.mean(axis=1)
    return np.array([middles[owner == s].mean(axis=0) for s in range(world.sensor_count)])
