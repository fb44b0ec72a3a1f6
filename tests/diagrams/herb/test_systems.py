"""The closed loop's LeafSystems in isolation: fixed inputs, fake cores, no plant."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from diagrams.herb.controller import HandController
from diagrams.herb.estimator import HandEstimator
from diagrams.herb.executor import EXECUTOR_STATE_SIZE, ActionExecutor
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import ConventionalParticleFilter
from models.herb.kinematics import JointPath
from models.planar.world import PlanarWorld
from planning.protocols import PlanResult

ACTIONS = np.array([[0.02, 0, 0], [0, 0.02, 0], [0, -0.02, 0], [0.02, 0.02, 0],
                    [0.02, -0.02, 0]])


class FakeMotion:
    """Straight joint paths; actions in ``infeasible`` are refused."""

    def __init__(self, infeasible=()):
        self.infeasible = set(infeasible)
        self.ik = type("IK", (), {"velocity_limits": np.ones(7)})()

    def plan(self, pose, q, action):
        a = int(np.flatnonzero((ACTIONS == action).all(axis=1))[0])
        poses = np.array([pose, pose + action / 2, pose + action])
        qs = np.array([q, q + 0.01, q + 0.02])
        if a in self.infeasible:
            return JointPath(poses[:1], qs[:1], False, f"action {a} collides")
        return JointPath(poses, qs, True)


class FakePlanner:
    def __init__(self, ranking):
        self.ranking = ranking
        self.calls = []

    def plan(self, belief, *, rng, memory, contact_seen, last_action, reading, palm_pose):
        self.calls.append((contact_seen, last_action, tuple(reading), memory))
        self.palm_pose = palm_pose
        return PlanResult(self.ranking[0], tuple(self.ranking), "post-contact", 1.0,
                          memory=len(self.calls))


def _belief(n=100):
    rng = np.random.default_rng(0)
    return ParticleBelief.uniform(np.column_stack([rng.uniform(0.3, 0.35, n),
                                                   rng.uniform(-0.05, 0.05, n),
                                                   rng.uniform(-np.pi, np.pi, n)]))


def test_estimator_updates_once_the_palm_has_travelled_5_mm():
    world = PlanarWorld.load("small_box", "fingertips")
    initial = _belief()
    system = HandEstimator(ConventionalParticleFilter(world), initial, 2,
                           travel_m=0.005, check_period_s=0.01)
    context = system.CreateDefaultContext()
    readings = system.GetInputPort("sensor_contact").FixValue(context, np.zeros(2))
    palm = system.GetInputPort("palm_pose").FixValue(context, np.zeros(3))
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.0)
    tracker = system.tracker(simulator.get_context())
    assert tracker is not None and tracker.updates == 0
    palm.GetMutableData().set_value(np.array([0.003, 0.0, 0.0]))  # 3 mm: not yet
    simulator.AdvanceTo(0.015)
    assert system.tracker(simulator.get_context()) is tracker
    palm.GetMutableData().set_value(np.array([0.01, 0.0, 0.0]))
    readings.GetMutableData().set_value(np.array([1.0, 0.0]))
    simulator.AdvanceTo(0.025)
    assert system.tracker(simulator.get_context()).updates == 1
    assert tracker.updates == 0  # the earlier value is unchanged: state is a value
    out = simulator.get_context()
    assert system.GetOutputPort("contact_seen").Eval(out)[0] == 1.0
    mean = system.GetOutputPort("mean").Eval(out)
    np.testing.assert_allclose(mean, system.GetOutputPort("belief").Eval(out).mean())


def _controller(planner, motion, on_infeasible="stop", horizon=5):
    system = HandController(planner, motion, ACTIONS, _belief(), 2, horizon=horizon,
                            on_infeasible=on_infeasible, check_period_s=0.02)
    context = system.CreateDefaultContext()
    system.GetInputPort("belief").FixValue(context, _belief())
    system.GetInputPort("contact_seen").FixValue(context, [1.0])
    system.GetInputPort("sensor_contact").FixValue(context, [0.0, 1.0])
    executor = np.zeros(EXECUTOR_STATE_SIZE)
    executor[-1] = 1.0  # idle
    port = system.GetInputPort("executor_state").FixValue(context, executor)
    return system, context, port


def test_controller_sends_the_best_feasible_action_when_the_executor_is_idle():
    planner = FakePlanner([3, 0, 1, 2, 4])
    system, context, _ = _controller(planner, FakeMotion(infeasible={3}), on_infeasible="next")
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.0)
    np.testing.assert_array_equal(system.GetOutputPort("command").Eval(context), [1, 0])
    decision = system.decisions(context)[0]
    assert decision.action == 0 and decision.rejected == ((3, "action 3 collides"),)
    assert planner.calls == [(True, None, (False, True), None)]


def test_controller_keeps_the_planner_memory_in_its_context_and_hands_it_back():
    planner = FakePlanner([0, 1, 2, 3, 4])
    system, context, _ = _controller(planner, FakeMotion(), horizon=3)
    copy = context.Clone()
    Simulator(system, context).AdvanceTo(0.05)
    assert [call[3] for call in planner.calls] == [None, 1, 2]
    assert [call[1] for call in planner.calls] == [None, 0, 0]
    # a context cloned before the run starts afresh: nothing was shared
    assert system.decisions(copy) == ()
    Simulator(system, copy).AdvanceTo(0.0)
    assert planner.calls[-1][3] is None and len(system.decisions(copy)) == 1


def test_controller_stops_when_the_preferred_action_is_infeasible():
    system, context, _ = _controller(FakePlanner([3, 0, 1, 2, 4]), FakeMotion(infeasible={3}))
    Simulator(system, context).AdvanceTo(0.05)
    np.testing.assert_array_equal(system.GetOutputPort("command").Eval(context), [1, -1])
    assert system.finished(context) and len(system.decisions(context)) == 1


def test_controller_waits_while_the_executor_moves():
    planner = FakePlanner([0, 1, 2, 3, 4])
    system, context, port = _controller(planner, FakeMotion())
    busy = np.zeros(EXECUTOR_STATE_SIZE)
    port.GetMutableData().set_value(busy)
    Simulator(system, context).AdvanceTo(0.1)
    assert planner.calls == [] and system.GetOutputPort("command").Eval(context)[1] == -1


def test_controller_rejects_unknown_infeasibility_rule():
    with pytest.raises(ValueError, match="on_infeasible"):
        HandController(FakePlanner([0]), FakeMotion(), ACTIONS, _belief(), 2, horizon=1,
                       on_infeasible="clip")


def test_executor_tracks_the_commanded_path_and_refuses_infeasible_commands():
    start_pose, start_q = np.array([0.5, -0.2, 0.0]), np.zeros(7)
    system = ActionExecutor(FakeMotion(infeasible={2}), ACTIONS, start_pose, start_q,
                            hand_speed_m_per_s=0.05, settle_s=0.1, check_period_s=0.02)
    context = system.CreateDefaultContext()
    command = system.GetInputPort("command").FixValue(context, [0.0, -1.0])
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.15)
    assert system.GetOutputPort("executor_state").Eval(context)[-1] == 0.0  # settling
    simulator.AdvanceTo(0.25)
    assert system.GetOutputPort("executor_state").Eval(context)[-1] == 1.0
    command.GetMutableData().set_value(np.array([1.0, 0.0]))
    simulator.AdvanceTo(0.3)
    motion = system.motion(context)
    assert motion.decision == 1 and motion.refused == 0
    assert system.GetOutputPort("executor_state").Eval(context)[-1] == 0.0  # moving
    end = motion.trajectory.end_time()
    assert end - motion.trajectory.start_time() == pytest.approx(0.02 / 0.05)
    simulator.AdvanceTo(end + 0.15)
    status = system.GetOutputPort("executor_state").Eval(context)
    np.testing.assert_allclose(status[:3], start_pose + ACTIONS[0])
    np.testing.assert_allclose(status[3:10], np.full(7, 0.02))
    desired = system.GetOutputPort("arm_desired_state").Eval(context)
    np.testing.assert_allclose(desired, np.concatenate([np.full(7, 0.02), np.zeros(7)]),
                               atol=1e-12)
    command.GetMutableData().set_value(np.array([2.0, 2.0]))
    simulator.AdvanceTo(end + 0.25)
    motion = system.motion(context)
    assert motion.decision == 2 and motion.refused == 1
    np.testing.assert_allclose(motion.pose, start_pose + ACTIONS[0])


def test_planar_poses_reads_the_palm_and_the_object_from_body_poses():
    from pydrake.math import RigidTransform, RotationMatrix
    from pydrake.systems.framework import DiagramBuilder

    from diagrams.herb.poses import PlanarPoses
    from diagrams.herb.station import add_herb_plant
    from models.herb.mount import X_W_palm
    from models.herb.scene import SceneSpec
    from models.herb.tactile import TactileLayout

    scene = SceneSpec.load("closed_loop")
    plant, _, herb = add_herb_plant(DiagramBuilder(), scene,
                                    layout=TactileLayout.load("distal_links"))
    system = PlanarPoses(plant, herb)
    context = system.CreateDefaultContext()
    poses = [RigidTransform()] * plant.num_bodies()
    palm = herb.hand.palm_frame
    X_WP = X_W_palm(np.array([0.7, -0.2, 0.3]), herb.palm_height_m)
    poses[int(palm.body().index())] = X_WP @ palm.GetFixedPoseInBodyFrame().inverse()
    tipped = RotationMatrix.MakeZRotation(0.4) @ RotationMatrix.MakeXRotation(0.2)
    poses[int(herb.object_body.index())] = RigidTransform(tipped, [0.9, -0.1, 0.8])
    system.get_input_port().FixValue(context, poses)
    np.testing.assert_allclose(system.GetOutputPort("palm_pose").Eval(context),
                               [0.7, -0.2, 0.3], atol=1e-12)
    object_pose = system.GetOutputPort("object_pose").Eval(context)
    np.testing.assert_allclose(object_pose, [0.9, -0.1, 0.4], atol=1e-12)
    np.testing.assert_allclose(system.GetOutputPort("object_tilt").Eval(context), [0.2],
                               atol=1e-12)
