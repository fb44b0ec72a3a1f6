"""Planar-hand inverse kinematics: reaching, warm-started paths, infeasibility reported."""

import numpy as np
import pytest

from models.herb.kinematics import (
    ClosePair,
    PlanarHandIK,
    format_mm,
    straight_push_path,
    time_parameterize,
)
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


@pytest.fixture(scope="module")
def right_ik() -> PlanarHandIK:
    return PlanarHandIK(SceneSpec.load("right_obstacles"))


@pytest.fixture(scope="module")
def inside_cracker_box(right_ik) -> np.ndarray:
    """A palm pose 2 cm behind the cracker box's centre: reachable, but inside the box."""
    cracker = next(o for o in right_ik.world.scene.obstacles if o.spec.name == "cracker_box")
    return np.array([cracker.pose.x - 0.02, cracker.pose.y, 0.0])


def test_target_inside_an_obstacle_is_a_collision_naming_obstacle_and_link(
        right_ik, inside_cracker_box):
    """From HERB's home and from random seeds the failure is a collision with the cracker
    box, not "unreachable", even though the last seed (the fourth of this generator) cannot
    reach the pose at all."""
    result = right_ik.solve_multistart(inside_cracker_box, rng=np.random.default_rng(0),
                                       attempts=4)
    assert not result.feasible
    assert result.reason.startswith("collision"), result.reason
    assert "obstacle 'cracker_box'" in result.reason
    assert "robot link 'bh_" in result.reason  # the hand is in the box
    assert result.blocking and result.blocking[0].other == "cracker_box"
    assert result.blocking[0].distance_m < 0  # penetrating


def test_single_solve_inside_an_obstacle_names_it(right_ik, inside_cracker_box):
    result = right_ik.solve(inside_cracker_box, right_ik.home)
    assert not result.feasible and result.reason.startswith("collision")
    deepest = result.blocking[0]
    assert deepest.robot_link.startswith("bh_")
    assert (f"robot link '{deepest.robot_link}' (geometry '{deepest.robot_geometry}') "
            f"penetrates obstacle 'cracker_box' by {-deepest.distance_m * 1e3:.2f} mm"
            in result.reason)


def test_clearance_failure_does_not_read_as_a_contradiction(right_ik, inside_cracker_box):
    """The clearance-keeping solve from home ends 5.03 mm from everything: what failed is
    reaching the pose, and the message says so instead of "no solution keeps 0.005 m
    clearance (closest 0.0050 m)"."""
    result = right_ik.solve(inside_cracker_box, right_ik.home)
    assert result.min_distance_m >= right_ik.clearance_m
    assert "0.0050 m" not in result.reason
    assert "5.00 mm clearance" in result.reason
    assert "misses the pose by" in result.reason


def test_distances_near_the_clearance_print_distinct_digits():
    pair = ClosePair(0.0049996, "bh_f1_distal", "f1_tip", "cracker_box", "cracker_box",
                     "obstacle")
    text = pair.describe(0.005)
    assert "is 4.9996 mm from obstacle 'cracker_box'" in text
    assert format_mm(0.005, 0.0049996) == "5.0000"
    assert format_mm(0.00487, 0.005) == "4.87"
    self_pair = ClosePair(-0.001, "wam3", "wam3_collision_0", "wam6", "wam6_collision_0",
                          "robot link")
    assert self_pair.describe(0.005) == ("robot link 'wam3' (geometry 'wam3_collision_0') "
                                         "penetrates robot link 'wam6' (geometry "
                                         "'wam6_collision_0') by 1.00 mm")


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
