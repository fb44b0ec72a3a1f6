"""Hand-frame actions as arm motions (the closed loop's IK executor)."""

import numpy as np
import pytest

from models.herb.kinematics import PlanarHandIK
from models.herb.motion import HandMotionPlanner, world_target
from models.herb.scene import SceneSpec


@pytest.fixture(scope="module")
def closed_loop_ik():
    return PlanarHandIK(SceneSpec.load("closed_loop"))


@pytest.fixture(scope="module")
def start(closed_loop_ik):
    pose = closed_loop_ik.world.scene.hand_start.as_array()
    result = closed_loop_ik.solve_multistart(pose, rng=np.random.default_rng(0))
    assert result.feasible
    return pose, result.q


def test_world_target_turns_hand_frame_actions_with_the_hand():
    facing_left = np.array([0.5, -0.2, np.pi / 2])
    target = world_target(facing_left, np.array([0.02, 0.0, 0.0]))  # forward = world +y
    np.testing.assert_allclose(target, [0.5, -0.18, np.pi / 2], atol=1e-12)
    target = world_target(facing_left, np.array([0.0, 0.02, 0.0]))  # left = world -x
    np.testing.assert_allclose(target, [0.48, -0.2, np.pi / 2], atol=1e-12)


def test_a_forward_action_is_solved_every_step_and_reaches_its_target(closed_loop_ik, start):
    pose, q = start
    motion = HandMotionPlanner(closed_loop_ik, step_m=0.005)
    path = motion.plan(pose, q, np.array([0.02, 0.02, 0.0]))
    assert path.feasible and path.reason == ""
    assert path.q.shape == (7, 7) and path.poses.shape == (7, 3)  # ceil(2.83 / 0.5) + 1
    reached = closed_loop_ik.palm_pose(path.q[-1])
    np.testing.assert_allclose(reached[:2], pose[:2] + 0.02, atol=1e-3)
    assert abs(reached[2] - pose[2]) < 2e-3
    assert motion.plan(pose, q, np.array([0.02, 0.02, 0.0])) is path  # kept for the executor


def test_unreachable_and_off_table_actions_are_reported_not_clipped(closed_loop_ik, start):
    pose, q = start
    motion = HandMotionPlanner(closed_loop_ik, step_m=0.01)
    far = motion.plan(pose, q, np.array([0.60, 0.0, 0.0]))
    assert not far.feasible and "unreachable" in far.reason
    assert len(far.poses) >= 2  # the reachable part is kept, the rest refused
    off_table = motion.plan(np.array([0.56, -0.91, 0.0]), q, np.array([0.0, -0.03, 0.0]))
    assert not off_table.feasible and "leave the table" in off_table.reason


def test_bad_step_is_rejected(closed_loop_ik):
    with pytest.raises(ValueError, match="step_m"):
        HandMotionPlanner(closed_loop_ik, step_m=0.0)


def test_negative_posture_weight_is_rejected():
    with pytest.raises(ValueError, match="posture_weight must be >= 0"):
        PlanarHandIK(SceneSpec.load("closed_loop"), posture_weight=-0.1)
