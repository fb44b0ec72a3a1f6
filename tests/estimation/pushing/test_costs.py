"""The seed-003 costs: residuals at known configurations and analytic Jacobians against
central differences along GTSAM's Pose2 retraction."""

import gtsam
import numpy as np
import pytest

from estimation.pushing.costs import (
    closest_boundary_point,
    contact_points,
    contact_residual,
    limit_surface_c,
    motion_residual,
    penetration_residual,
    stationary_residual,
    vision_residual,
)

SQUARE = np.array([[-0.045, -0.045], [0.045, -0.045], [0.045, 0.045], [-0.045, 0.045]])


def retract(pose, xi):
    """The pose moved by the local perturbation xi, through gtsam.Pose2 (its own chart)."""
    moved = gtsam.Pose2(*pose).retract(np.asarray(xi, dtype=float))
    return np.array([moved.x(), moved.y(), moved.theta()])


def numerical(f, pose, step=1e-6):
    columns = []
    for k in range(3):
        xi = np.zeros(3)
        xi[k] = step
        columns.append((f(retract(pose, xi)) - f(retract(pose, -xi))) / (2 * step))
    return np.column_stack(columns)


def test_closest_point_and_signed_distance_on_a_square():
    A, dA, sd, grad = closest_boundary_point(SQUARE, np.array([0.06, 0.01]))
    np.testing.assert_allclose(A, [0.045, 0.01])
    np.testing.assert_allclose(dA, [[0, 0], [0, 1]], atol=1e-12)
    assert sd == pytest.approx(0.015)
    np.testing.assert_allclose(grad, [1, 0], atol=1e-12)
    _, _, sd_in, grad_in = closest_boundary_point(SQUARE, np.array([0.04, 0.0]))
    assert sd_in == pytest.approx(-0.005)
    np.testing.assert_allclose(grad_in, [1, 0], atol=1e-12)
    _, dA_corner, sd_corner, _ = closest_boundary_point(SQUARE, np.array([0.05, 0.05]))
    assert sd_corner == pytest.approx(np.sqrt(2) * 0.005)
    np.testing.assert_allclose(dA_corner, 0.0)


def test_contact_residual_is_zero_for_a_touching_rod_pushing_along_the_normal():
    pose = np.array([0.1, 0.2, 0.3])
    radius = 0.003125
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s], [s, c]])
    rod = pose[:2] + R @ np.array([-0.045 - radius, 0.01])
    force = R @ np.array([2.0, 0.0])
    r, _ = contact_residual(pose, rod, force, radius, SQUARE)
    np.testing.assert_allclose(r, 0.0, atol=1e-12)


def test_penetration_is_the_depth_of_a_rod_inside_and_zero_outside():
    pose = np.array([0.1, 0.2, 0.3])
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s], [s, c]])
    radius = 0.003
    inside = pose[:2] + R @ np.array([-0.045 - radius + 0.002, 0.01])  # 2 mm in
    r, J = penetration_residual(pose, inside, radius, SQUARE)
    assert r[0] == pytest.approx(0.002)
    Jn = numerical(lambda x: penetration_residual(x, inside, radius, SQUARE)[0], pose)
    np.testing.assert_allclose(J, Jn, atol=1e-6)
    outside = pose[:2] + R @ np.array([-0.045 - radius - 0.001, 0.01])
    r, J = penetration_residual(pose, outside, radius, SQUARE)
    assert r[0] == 0.0 and not J.any()


@pytest.mark.parametrize("seed", range(5))
def test_contact_jacobian_matches_numerical(seed):
    rng = np.random.default_rng(seed)
    pose = rng.normal(0, [0.05, 0.05, 1.0])
    rod = pose[:2] + rng.normal(0, 0.05, 2)
    force = rng.normal(0, 1, 2)
    _, J = contact_residual(pose, rod, force, 0.003, SQUARE)
    Jn = numerical(lambda x: contact_residual(x, rod, force, 0.003, SQUARE)[0], pose)
    np.testing.assert_allclose(J, Jn, atol=1e-6)


@pytest.mark.parametrize("seed", range(5))
def test_motion_jacobians_match_numerical(seed):
    rng = np.random.default_rng(seed)
    previous = rng.normal(0, [0.05, 0.05, 1.0])
    current = previous + rng.normal(0, [0.002, 0.002, 0.02])
    rods = previous[:2] + rng.normal(0, 0.05, (2, 2))
    forces = rng.normal(0, 1, (2, 2))
    points = contact_points(rods, forces, 0.003)
    np.testing.assert_allclose(np.linalg.norm(points - rods, axis=1), 0.003)
    _, J1, J2 = motion_residual(previous, current, forces, points, 0.038)
    n1 = numerical(lambda x: motion_residual(x, current, forces, points, 0.038)[0], previous)
    n2 = numerical(lambda x: motion_residual(previous, x, forces, points, 0.038)[0], current)
    np.testing.assert_allclose(J1, n1, atol=1e-8)
    np.testing.assert_allclose(J2, n2, atol=1e-8)


def test_motion_residual_vanishes_for_the_limit_surface_twist():
    """A push through the centre along +x moves the object along +x without turning; an
    off-centre push turns it with w / v = m / (c^2 F) (the ellipsoidal limit surface)."""
    c = 0.038
    previous = np.array([0.0, 0.0, 0.0])
    forces = np.array([[1.0, 0.0]])
    centred = np.array([[-0.045, 0.0]])
    r, _, _ = motion_residual(previous, np.array([0.001, 0.0, 0.0]), forces, centred, c)
    np.testing.assert_allclose(r, 0.0, atol=1e-15)
    offset = np.array([[-0.045, 0.02]])
    m = -0.02 * 1.0  # r x f = (-0.045)(0) - (0.02)(1)
    v = 0.001
    w = v * m / (c * c * 1.0)
    r, _, _ = motion_residual(previous, np.array([v, 0.0, w]), forces, offset, c)
    np.testing.assert_allclose(r, 0.0, atol=1e-15)
    r_wrong, _, _ = motion_residual(previous, np.array([v, 0.0, -w]), forces, offset, c)
    assert np.abs(r_wrong).max() > 1e-6


def test_vision_and_stationary_jacobians_match_numerical():
    pose = np.array([0.1, -0.2, 3.1])
    measured = np.array([0.09, -0.19, -3.1])
    r, J = vision_residual(pose, measured)
    assert r[2] == pytest.approx(6.2 - 2 * np.pi)
    np.testing.assert_allclose(J, numerical(lambda x: vision_residual(x, measured)[0], pose),
                               atol=1e-8)
    other = np.array([0.11, -0.21, 3.0])
    _, J1, J2 = stationary_residual(other, pose)
    np.testing.assert_allclose(J1, numerical(lambda x: stationary_residual(x, pose)[0], other),
                               atol=1e-8)
    np.testing.assert_allclose(J2, numerical(lambda x: stationary_residual(other, x)[0], pose),
                               atol=1e-8)


def test_limit_surface_c_of_the_90mm_square_and_a_disk():
    assert limit_surface_c(SQUARE) == pytest.approx(0.0345, abs=5e-4)
    a = 2 * np.pi * np.arange(128) / 128
    disk = 0.05 * np.column_stack([np.cos(a), np.sin(a)])
    assert limit_surface_c(disk) == pytest.approx(2 * 0.05 / 3, rel=0.01)
