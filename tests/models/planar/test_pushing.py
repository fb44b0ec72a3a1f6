"""The quasi-static pushing model: Lynch's formulas, continuity, stepping."""

import numpy as np

from models.planar.pushing import lynch_twist, truncated_normal


def _one(v):
    return np.atleast_2d(np.asarray(v, dtype=float))


def test_sticking_moves_the_contact_point_with_the_pusher():
    r, n = _one([-0.025, 0.02]), _one([1.0, 0.0])
    vp = _one([1.0, 0.1])
    V = lynch_twist(r, n, vp, np.array([10.0]), np.array([0.05]))[0]
    contact_velocity = [V[0] - V[2] * r[0, 1], V[1] + V[2] * r[0, 0]]
    assert np.allclose(contact_velocity, vp[0])
    assert V[2] < 0  # pushed forward left of the centre: turns clockwise


def test_centred_push_translates_and_separation_stops():
    r, n = _one([-0.025, 0.0]), _one([1.0, 0.0])
    V = lynch_twist(r, n, _one([1.0, 0.0]), np.array([0.5]), np.array([0.05]))[0]
    assert np.allclose(V, [1.0, 0.0, 0.0])
    assert np.allclose(lynch_twist(r, n, _one([-1.0, 0.0]), np.array([0.5]),
                                   np.array([0.05])), 0.0)


def test_twist_is_continuous_across_the_sticking_sliding_boundary():
    r, n, c = _one([-0.025, 0.03]), _one([1.0, 0.0]), np.array([0.04])
    angles = np.linspace(-1.2, 1.2, 2001)
    vp = np.column_stack([np.cos(angles), np.sin(angles)])
    V = lynch_twist(np.repeat(r, len(angles), 0), np.repeat(n, len(angles), 0), vp,
                    np.full(len(angles), 0.4), np.repeat(c, len(angles)))
    jumps = np.abs(np.diff(V, axis=0)).max(axis=1)
    # the boundary is crossed (both regimes occur) without a jump larger than the
    # neighbouring steps' (a slipped formula jumps by orders of magnitude)
    assert jumps.max() < 3 * np.median(jumps)
    # sliding keeps the pusher's normal velocity
    vc_n = V[:, 0] - V[:, 2] * r[0, 1]
    assert np.allclose(vc_n, vp[:, 0])


def test_truncated_normal_is_positive_and_centred():
    u = (np.arange(20000) + 0.5) / 20000
    x = truncated_normal(u, 0.5, 0.2)
    assert x.min() > 0 and abs(np.median(x) - 0.5) < 0.01


def test_box_pushed_squarely_translates_with_the_hand(box_world):
    start = np.array([[0.15, 0.0, 0.0]])
    action = np.array([0.1, 0.0, 0.0])
    u = np.full((1, box_world.uniforms_per_step(action)), 0.5)
    end = box_world.step(start, action, u)[0]
    # the box is in contact with both fingertips (front x = 0.1166 m), not rotated
    assert np.isclose(end[0] - 0.025, 0.1166, atol=1e-3)
    assert abs(end[1]) < 2e-4 and abs(end[2]) < 5e-3  # contacts resolved one at a time


def test_steps_are_deterministic_given_uniforms_and_leave_no_overlap(box_world):
    rng = np.random.default_rng(2)
    states = box_world.sample_gaussian([0.18, 0.0, 0.0], [0.02, 0.05, 1.0], 300, rng=rng)
    action = np.array([0.1, 0.0, 0.0])
    u = rng.random((300, box_world.uniforms_per_step(action)))
    a = box_world.step(states, action, u)
    b = box_world.step(states, action, u)
    assert np.array_equal(a, b)
    assert box_world.sensing.hand_distance(a).min() > -2e-4
    assert box_world.in_contact(a).mean() > 0.5


def test_off_centre_push_rotates_the_box_towards_the_free_side(box_world):
    action = np.array([0.08, 0.0, 0.0])
    u = np.full((2, box_world.uniforms_per_step(action)), 0.5)
    end = box_world.step(np.array([[0.16, 0.05, 0.0], [0.16, -0.05, 0.0]]), action, u)
    assert end[0, 2] > 0.05 and end[1, 2] < -0.05  # mirror images turn opposite ways
    assert np.isclose(end[0, 2], -end[1, 2], atol=1e-6)
