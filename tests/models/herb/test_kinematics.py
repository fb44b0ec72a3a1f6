"""Planar-hand inverse kinematics: reaching, warm-started paths, infeasibility reported."""

import numpy as np
import pytest

from models.herb.kinematics import PlanarHandIK, straight_push_path, time_parameterize
from models.herb.scene import SceneSpec


def test_feasible_pose_is_reached_within_tolerance(empty_ik):
    target = np.array([0.75, -0.25, 0.2])
    result = empty_ik.solve_multistart(target, rng=np.random.default_rng(0))
    assert result.feasible, result.reason
    x, y, theta, z = empty_ik.palm_pose(result.q)
    np.testing.assert_allclose([x, y, theta], target, atol=2e-3)
    assert z == pytest.approx(empty_ik.world.palm_height_m, abs=2e-4)
    assert np.all(result.q >= empty_ik.lower) and np.all(result.q <= empty_ik.upper)
    assert result.min_distance_m >= empty_ik.clearance_m - 1e-4


def test_unreachable_target_is_reported_not_clipped(empty_ik):
    result = empty_ik.solve(np.array([1.6, -0.25, 0.0]), empty_ik.home)
    assert not result.feasible
    assert result.reason.startswith("unreachable")


def test_target_inside_an_obstacle_is_a_collision():
    scene = SceneSpec.load("right_obstacles")
    ik = PlanarHandIK(scene)
    cracker = next(o for o in scene.obstacles if o.spec.name == "cracker_box").pose
    result = ik.solve_multistart(np.array([cracker.x - 0.02, cracker.y, 0.0]),
                                 rng=np.random.default_rng(0), attempts=6)
    assert not result.feasible
    assert "collision" in result.reason or "unreachable" in result.reason


def test_straight_path_is_smooth_and_timed_within_velocity_limits(empty_ik, empty_scene):
    start = empty_scene.hand_start.as_array()
    first = empty_ik.solve_multistart(start, rng=np.random.default_rng(0))
    path = straight_push_path(empty_ik, start, 0.1, first.q, step_m=0.02)
    assert path.feasible, path.reason
    assert path.q.shape == (6, 7)
    assert np.abs(np.diff(path.q, axis=0)).max() < 0.3  # warm-started: no branch jumps
    times = time_parameterize(path.q, path.poses, hand_speed_m_per_s=0.05,
                              velocity_limits=empty_ik.velocity_limits)
    speeds = np.abs(np.diff(path.q, axis=0)) / np.diff(times)[:, None]
    assert np.all(speeds <= 0.8 * empty_ik.velocity_limits + 1e-9)
    assert times[-1] >= 0.1 / 0.05 - 1e-9


def test_infeasible_path_stops_at_the_first_bad_pose(empty_ik, empty_scene):
    start = empty_scene.hand_start.as_array()
    first = empty_ik.solve_multistart(start, rng=np.random.default_rng(0))
    path = straight_push_path(empty_ik, start, 1.0, first.q, step_m=0.1)
    assert not path.feasible
    assert "pose" in path.reason and len(path.poses) < 11
