"""The closed loop: HERB pushes an object into a goal region in front of its palm by touch,
in one Drake diagram (thesis sec. 6.5, in simulation).

::

    plant --contact results--> TactileSensor --sensor_contact--> HandEstimator --belief-->
      ^                                                              ^           HandController
      |                        PlanarPoses --palm_pose---------------+                |
      +--arm desired state-- ActionExecutor <--command-----------------------------------+
                                   +--executor_state (idle, commanded pose, q)--> controller

An episode (:func:`run_episode`) draws the object's true pose from the initial belief
(hand frame), places it on the table in front of the hand, and runs until the controller
stops (its horizon, or no feasible action), the object leaves the table, or a time limit.
Success is the thesis' rule: the object's centre is in the goal region when the episode
ends. The summary reports the steps, the time to reach the goal, the final distance to
it, the estimator's error over time and the planning time per decision.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from tqdm import tqdm

from diagrams.belief_drawing import BeliefDrawer
from diagrams.herb.station import add_herb_plant, add_meshcat
from diagrams.herb.systems import (
    ActionExecutor,
    HandController,
    HandEstimator,
    PlanarPoses,
)
from diagrams.tactile_sensor import TactileSensor
from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import ConventionalParticleFilter, ManifoldParticleFilter
from models.contact import SimulationConfig
from models.herb.kinematics import PlanarHandIK
from models.herb.motion import HandMotionPlanner
from models.herb.scene import PlanarPose, SceneSpec
from models.herb.tactile import SensorGroups, TactileLayout, TactileNoise
from models.herb.world import HerbWorld
from models.objects import ObjectSpec
from models.se2 import compose, inverse
from planning.hand.model import goal_region
from planning.hand.planner import HandPlanner, ThesisHandPlanner
from planning.hand.precontact import PreContactSettings
from planning.hand.solution import HandSolution

ESTIMATORS = ("mpf", "cpf")
PLANNER_BELIEFS = ("estimator", "thesis")
POLICIES = ("qmdp", "pomdp")
#: The thesis' three initial beliefs (sec. 6.5): means 35 cm ahead at lateral offsets 12,
#: 0 and 6 cm; its figure shows the first to the hand's right (-y).
THESIS_BELIEF_MEANS = ((0.35, -0.12, 0.0), (0.35, 0.0, 0.0), (0.35, 0.06, 0.0))
TOPPLED_RAD = float(np.deg2rad(45.0))
"""An object tilted further than this has fallen over; the episode ends."""


class InfeasibleStart(RuntimeError):
    """The hand's start pose cannot be reached (IK)."""


@dataclass(frozen=True)
class EpisodeSettings:
    """One closed-loop episode.

    Attributes:
        scene: scene name or path (its object is replaced by ``object_name``).
        object_name: the pushed object; it must be the planning model's. The thesis'
            real-robot trials pushed a bottle (sec. 6.5), and so do these: the small box
            of the simulations (3.5 cm x 5 cm, 12 cm tall) topples in Drake when a finger
            pushes it above about 5 cm, which HERB's fingers do (F2 at about 8.5 cm).
        policy: post-contact policy, ``qmdp`` or ``pomdp``.
        estimator: ``mpf`` (manifold particle filter, analytic manifold) or ``cpf``.
        planner_belief: what the policy acts on: ``estimator`` (the estimator system's
            belief, discretised after contact; :class:`~planning.hand.planner.HandPlanner`)
            or ``thesis`` (the policy's own particle filter, then the planning model's
            discrete Bayes filter, sec. 6.4.1;
            :class:`~planning.hand.planner.ThesisHandPlanner`).
        belief_mean: (x m, y m, theta rad) of the initial belief, hand frame.
        belief_std: its standard deviations (thesis sec. 6.5: 5 cm; 15 deg as sec. 6.4.2).
        particles: estimator particles.
        horizon: decisions per episode.
        on_infeasible: ``stop``: the episode ends when the policy's action is infeasible
            (the thesis' real-robot rule, sec. 6.5); ``next``: fall back to the next-ranked
            feasible action (at the arm's reach this drags a captured object sideways, so
            it is not the default).
        precontact: the pre-contact search's settings.
        hand_speed_m_per_s: nominal palm speed.
        travel_m: palm travel between estimator updates (m).
        posture_weight: the IK's pull towards HERB's home posture
            (:class:`~models.herb.kinematics.PlanarHandIK`); without it (0) warm-started
            motions drift into postures that collide in the middle of the workspace (4 of
            40 forward-biased random walks, against none with 0.05).
        layout: Drake tactile layout (``distal_links``: every face of each distal link).
        noise: the tactile sensors' noise (thesis: 10 % wrong readings during contact).
        time_step_s: the plant's time step.
        seed: seeds the true pose, the particles, the sensors' noise, the filter and the
            planner.
    """

    scene: str = "closed_loop"
    object_name: str = "bottle"
    policy: str = "pomdp"
    estimator: str = "mpf"
    planner_belief: str = "estimator"
    belief_mean: tuple[float, float, float] = THESIS_BELIEF_MEANS[1]
    belief_std: tuple[float, float, float] = (0.05, 0.05, float(np.deg2rad(15.0)))
    particles: int = 500
    horizon: int = 30
    on_infeasible: str = "stop"
    precontact: PreContactSettings = field(default_factory=PreContactSettings)
    hand_speed_m_per_s: float = 0.05
    travel_m: float = 0.005
    posture_weight: float = 0.05
    layout: str = "distal_links"
    noise: TactileNoise = field(default_factory=TactileNoise)
    time_step_s: float = SimulationConfig().time_step_s
    seed: int = 0

    def __post_init__(self):
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"estimator must be one of {ESTIMATORS}, got {self.estimator!r}")
        if self.planner_belief not in PLANNER_BELIEFS:
            raise ValueError(f"planner_belief must be one of {PLANNER_BELIEFS}, got "
                             f"{self.planner_belief!r}")
        if self.particles < 10 or self.horizon < 1:
            raise ValueError("particles must be >= 10 and horizon >= 1")
        if self.on_infeasible not in ("next", "stop"):
            raise ValueError(f"on_infeasible must be 'next' or 'stop', got "
                             f"{self.on_infeasible!r}")


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


def make_filter(kind: str, world):
    """A filter factory for the estimator system; the analytic manifold (built once here,
    about 10 s for the small box at the thesis' 1.15 deg) is shared by every filter it
    makes."""
    if kind == "cpf":
        return lambda: ConventionalParticleFilter(world)
    manifold = AnalyticManifold(world)
    return lambda: ManifoldParticleFilter(world, manifold)


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


def build_closed_loop(settings: EpisodeSettings, solution: HandSolution, scene: SceneSpec,
                      ik: PlanarHandIK, q_start: np.ndarray, initial: ParticleBelief, *,
                      meshcat: Meshcat | None = None, filter_factory=None
                      ) -> ClosedLoopDiagram:
    """Wire the diagram of the module docstring for ``scene`` (the object already placed),
    the arm starting at ``q_start`` (7,) rad with the palm at the scene's hand start, and
    the estimator starting from ``initial``."""
    model, world = solution.model, solution.model.world
    motion = HandMotionPlanner(ik)
    builder = DiagramBuilder()
    sim = SimulationConfig(time_step_s=settings.time_step_s)
    layout = TactileLayout.load(settings.layout)
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
    factory = filter_factory or make_filter(settings.estimator, world)
    estimator = builder.AddSystem(HandEstimator(factory, initial, world.sensor_count,
                                                seed=settings.seed, travel_m=settings.travel_m))
    builder.Connect(tactile.GetOutputPort("sensor_contact"),
                    estimator.GetInputPort("sensor_contact"))
    builder.Connect(poses.GetOutputPort("palm_pose"), estimator.GetInputPort("palm_pose"))
    actions = model.spec.action_vectors()
    post_contact = solution.policies[settings.policy]
    planner_type = HandPlanner if settings.planner_belief == "estimator" else ThesisHandPlanner
    controller = builder.AddSystem(HandController(
        lambda: planner_type(model, post_contact, settings.precontact), motion, actions,
        initial, world.sensor_count, horizon=settings.horizon,
        on_infeasible=settings.on_infeasible, seed=settings.seed))
    executor = builder.AddSystem(ActionExecutor(motion, actions, scene.hand_start.as_array(),
                                                q_start,
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
            height_m=herb.table_top_z_m + scene.object.height_m + 0.01))
        builder.Connect(estimator.GetOutputPort("belief"), drawer.GetInputPort("belief"))
        builder.Connect(poses.GetOutputPort("palm_pose"), drawer.GetInputPort("palm_pose"))
        builder.Connect(tactile.GetOutputPort("sensor_contact"),
                        drawer.GetInputPort("sensor_contact"))
    return ClosedLoopDiagram(builder.Build(), plant, herb, tactile, poses, estimator,
                             controller, executor, visualizer)


def run_episode(settings: EpisodeSettings, solution: HandSolution, *,
                meshcat: Meshcat | None = None, progress: bool = True,
                filter_factory=None) -> Episode:
    """Run one episode (see the module docstring).

    Args:
        settings: the episode.
        solution: the solved planning model (its object must be ``settings.object_name``).
        meshcat: draw and record there; ``None`` draws nothing.
        progress: show a progress bar over simulated time.
        filter_factory: from :func:`make_filter`, to share one manifold across episodes.

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
    true_rel = world.sample_gaussian(mean, std, 1, rng=rng)[0]
    initial = ParticleBelief.uniform(world.sample_gaussian(mean, std, settings.particles,
                                                           rng=rng))
    scene = SceneSpec.load(settings.scene, object_override=settings.object_name)
    start = scene.hand_start.as_array()
    ik = PlanarHandIK(scene, posture_weight=settings.posture_weight)
    first = ik.solve_multistart(start, rng=np.random.default_rng([settings.seed, 1]))
    if not first.feasible:
        raise InfeasibleStart(f"hand start {np.round(start, 3).tolist()}: {first.reason}")
    scene = replace(scene, object_pose=PlanarPose(*compose(start, true_rel)))
    loop = build_closed_loop(settings, solution, scene, ik, first.q, initial, meshcat=meshcat,
                             filter_factory=filter_factory)
    plant, herb, visualizer = loop.plant, loop.herb, loop.visualizer
    context = loop.diagram.CreateDefaultContext()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context),
                       herb.robot_positions(plant, first.q))
    simulator = Simulator(loop.diagram, context)
    if meshcat is not None:
        meshcat.SetProperty("/Grid", "visible", False)
        meshcat.SetCameraPose(camera_in_world=[start[0] + 0.75, start[1] + 0.45, 1.2],
                              target_in_world=[start[0] + 0.3, start[1], herb.table_top_z_m])
        visualizer.StartRecording(False)
    simulator.Initialize()

    wall = time.perf_counter()
    trace, stop = _advance_until_done(loop, simulator, scene, model, settings, progress)
    wall_s = time.perf_counter() - wall
    html = None
    if visualizer is not None:
        visualizer.StopRecording()
        visualizer.PublishRecording()
        html = meshcat.StaticHtml()
    arrays = {k: np.array(v) for k, v in trace.items()}
    root = simulator.get_context()
    decisions = loop.controller.decisions(loop.controller.GetMyContextFromRoot(root))
    refused = loop.executor.motion(loop.executor.GetMyContextFromRoot(root)).refused
    summary = _summary(settings, solution, arrays, decisions, goal_region(world, model.spec),
                       stop, wall_s, refused)
    return Episode(summary, arrays, _snapshots(decisions, arrays), html)


def _snapshots(decisions: list, trace: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    times = np.array([d.time_s for d in decisions])
    nearest = np.searchsorted(trace["time_s"], times).clip(0, len(trace["time_s"]) - 1)
    return {"time_s": times,
            "particles": np.array([np.asarray(d.belief.states) for d in decisions]),
            "true_rel": trace["true_rel"][nearest]}


def _advance_until_done(loop: ClosedLoopDiagram, simulator: Simulator, scene: SceneSpec,
                        model, settings: EpisodeSettings, progress: bool
                        ) -> tuple[dict[str, list], str]:
    """Simulate in 0.05 s steps, recording the trace, until the episode ends; returns the
    trace and why it ended."""
    poses, estimator, tactile = loop.poses, loop.estimator, loop.tactile
    controller, executor = loop.controller, loop.executor
    actions = model.spec.action_vectors()
    longest = float(np.max(np.linalg.norm(actions[:, :2], axis=1)))
    limit_s = 1.0 + settings.horizon * (longest / settings.hand_speed_m_per_s + 0.6) + 30.0
    chunk = 0.05
    trace: dict[str, list] = {k: [] for k in ("time_s", "palm", "object", "true_rel", "mean",
                                              "rmse_m", "rmse_rad", "in_goal", "readings")}
    stop = "time_limit"
    bar = tqdm(total=settings.horizon, desc=f"episode ({settings.policy})", unit="decision",
               disable=not progress, leave=False)
    while simulator.get_context().get_time() < limit_s:
        simulator.AdvanceTo(simulator.get_context().get_time() + chunk)
        root = simulator.get_context()
        palm = poses.GetOutputPort("palm_pose").Eval(poses.GetMyContextFromRoot(root))
        obj = poses.GetOutputPort("object_pose").Eval(poses.GetMyContextFromRoot(root))
        belief = estimator.GetOutputPort("belief").Eval(estimator.GetMyContextFromRoot(root))
        rel = compose(inverse(palm), obj)
        rmse = belief.rmse(rel)
        for key, value in (("time_s", root.get_time()), ("palm", palm), ("object", obj),
                           ("true_rel", rel), ("mean", belief.mean()), ("rmse_m", rmse[0]),
                           ("rmse_rad", rmse[1]), ("in_goal", bool(model.in_goal(rel[None])[0])),
                           ("readings", tactile.GetOutputPort("sensor_contact").Eval(
                               tactile.GetMyContextFromRoot(root)).copy())):
            trace[key].append(value)
        controller_context = controller.GetMyContextFromRoot(root)
        bar.update(len(controller.decisions(controller_context)) - bar.n)
        if not scene.table.contains(obj[0], obj[1], 0.01):
            stop = "object_left_table"
            break
        if poses.GetOutputPort("object_tilt").Eval(poses.GetMyContextFromRoot(root))[0] > \
                TOPPLED_RAD:
            stop = "object_toppled"
            break
        decisions = controller.decisions(controller_context)
        if controller.finished(controller_context) and _last_motion_done(executor, root,
                                                                         decisions):
            stop = "no_feasible_action" if decisions[-1].action < 0 else "horizon"
            break
    bar.close()
    return trace, stop


def _last_motion_done(executor: ActionExecutor, root, decisions: list) -> bool:
    """Has the executor finished (and settled after) the motion of the last decision, or,
    when that decision sent no action, the motion before it?"""
    context = executor.GetMyContextFromRoot(root)
    idle = executor.GetOutputPort("executor_state").Eval(context)[-1] > 0.5
    last_sent = len(decisions) if decisions[-1].action >= 0 else len(decisions) - 1
    return idle and executor.motion(context).decision >= last_sent


def _sensor_points(world) -> np.ndarray:
    """(S, 2) the centre of each planar sensor's segments (hand frame)."""
    segments, owner = world.hand.sensor_segments, world.hand.sensor_of_segment
    middles = segments.mean(axis=1)
    return np.array([middles[owner == s].mean(axis=0) for s in range(world.sensor_count)])


def distance_to_goal(rel: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(K,) distance (m) from each object centre (K, 3), hand frame, to the goal rectangle."""
    gap = np.maximum(np.maximum(goal[0] - rel[:, :2], rel[:, :2] - goal[1]), 0.0)
    return np.linalg.norm(gap, axis=1)


def _summary(settings, solution, trace, decisions, goal, stop, wall_s, refused) -> dict:
    in_goal = trace["in_goal"]
    reached = np.flatnonzero(in_goal)
    executed = [d for d in decisions if d.action >= 0]
    planning_ms = [d.planning_ms for d in decisions]
    names = solution.model.pomdp.actions
    sim_s = float(trace["time_s"][-1])
    settings_dict = asdict(settings)
    settings_dict["precontact"] = asdict(settings.precontact)
    return {
        "success": bool(in_goal[-1]),
        "stop_reason": stop,
        "steps": len(executed),
        "time_to_goal_s": float(trace["time_s"][reached[0]]) if len(reached) else None,
        "final_distance_to_goal_m": float(distance_to_goal(trace["true_rel"][-1:], goal)[0]),
        "final_object_pose_hand": trace["true_rel"][-1].tolist(),
        "initial_object_pose_hand": trace["true_rel"][0].tolist(),
        "estimator_rmse_m": {"mean": float(trace["rmse_m"].mean()),
                             "final": float(trace["rmse_m"][-1])},
        "estimator_rmse_deg": {"mean": float(np.rad2deg(trace["rmse_rad"]).mean()),
                               "final": float(np.rad2deg(trace["rmse_rad"][-1]))},
        "estimator_rmse_over_time": {"time_s": trace["time_s"][::4].tolist(),
                                     "rmse_m": trace["rmse_m"][::4].tolist(),
                                     "rmse_deg": np.rad2deg(trace["rmse_rad"][::4]).tolist()},
        "planning_ms": planning_ms,
        "planning_ms_median": float(np.median(planning_ms)) if planning_ms else None,
        "actions": [names[d.action] for d in executed],
        "phases": [d.phase for d in executed],
        "infeasible_actions": refused,
        "infeasible_rejected": sum(len(d.rejected) for d in decisions),
        "rejections": [{"time_s": d.time_s, "action": names[a], "reason": r}
                       for d in decisions for a, r in d.rejected],
        "post_contact_from_step": next((i for i, d in enumerate(executed)
                                        if d.phase == "post-contact"), None),
        "first_contact_reading_s": (float(trace["time_s"][np.argmax(trace["readings"].any(1))])
                                    if trace["readings"].any() else None),
        "sim_time_s": sim_s,
        "wall_time_s": wall_s,
        "real_time_factor": sim_s / wall_s,
        "goal_region_hand_m": goal.tolist(),
        "settings": settings_dict,
    }
