"""The Monte Carlo hand-relative POMDP: its tables against the continuous model."""

import numpy as np
import pytest

from planning.hand.discretization import ACTION_NAMES
from planning.hand.model import goal_region
from planning.pomdp.cassandra import read_pomdp, write_pomdp


def _free_index(model, ix, iy, k):
    disc = model.discretization
    raw = (ix * disc.shape_xy[1] + iy) * disc.theta_bins + k
    return int(model.kept[raw])


def test_far_from_the_hand_actions_shift_the_object_by_one_cell(small_hand_model):
    m = small_hand_model
    s = _free_index(m, 9, 4, 3)  # 18-20 cm ahead, nothing to touch
    forward, left = ACTION_NAMES.index("forward"), ACTION_NAMES.index("left")
    row = m.pomdp.T[forward].getrow(s)
    assert row.indices.tolist() == [_free_index(m, 8, 4, 3)] and row.data[0] == 1.0
    row = m.pomdp.T[left].getrow(s)  # the hand moves +y, so the object moves -y
    assert row.indices.tolist() == [_free_index(m, 9, 3, 3)]


def test_sentinel_is_absorbing_and_costs_one(small_hand_model):
    m = small_hand_model
    for t in m.pomdp.T:
        row = t.getrow(m.sentinel)
        assert row.indices.tolist() == [m.sentinel]
    assert (m.pomdp.R[m.sentinel] == -1).all()
    assert (m.pomdp.Z[:, m.sentinel, 0] == 1).all()


def test_rewards_follow_the_goal_region(small_hand_model):
    m = small_hand_model
    (x0, y0), (x1, y1) = goal_region(m.world, m.spec)
    assert x1 - x0 == pytest.approx(m.spec.goal_depth_m)
    assert y1 - y0 == pytest.approx(m.spec.goal_width_m)
    poses = m.discretization.representative_poses()
    states = m.index(poses)
    deep_inside = (poses[:, 0] > x0 + 0.015) & (poses[:, 0] < x1 - 0.015) & (
        np.abs(poses[:, 1]) < y1 - 0.015) & (states != m.sentinel)
    far = (poses[:, 0] > x1 + 0.03) & (states != m.sentinel)
    assert deep_inside.any() and far.any()
    assert (m.pomdp.R[states[deep_inside]] == 0).all()
    assert (m.pomdp.R[states[far]] == -1).all()


def test_free_states_read_no_contact_and_contact_states_can_read_sensors(small_hand_model):
    m = small_hand_model
    Z = m.pomdp.Z[0]
    assert np.allclose(Z[:m.free_count, 0], 1.0)
    contact = Z[m.free_count:m.sentinel]
    assert (contact[:, 1:].sum(axis=1) > 0.5).any()  # pieces on a fingertip fire it
    assert np.allclose(Z.sum(axis=1), 1.0)


def test_contact_is_reached_by_pushing_into_the_hand(small_hand_model):
    m = small_hand_model
    poses = np.array([[0.15, 0.0, np.pi / 2]])  # 1.5 cm beyond the fingertips
    s = int(m.index(poses)[0])
    assert s < m.free_count
    row = m.pomdp.T[ACTION_NAMES.index("forward")].getrow(s)
    reached = row.indices[row.data > 0]
    assert m.discretization.is_contact_state(
        np.flatnonzero(m.kept >= 0)[reached]).any()


def test_belief_of_particles_is_a_distribution(small_hand_model):
    m = small_hand_model
    poses = np.array([[0.18, 0.0, 0.0], [0.18, 0.0, 0.0], [0.5, 0.0, 0.0]])
    b = m.belief(poses)
    assert b.sum() == 1.0 and b[m.sentinel] == 1 / 3


def test_model_round_trips_through_cassandra(small_hand_model, tmp_path):
    path = tmp_path / "hand.pomdp"
    write_pomdp(small_hand_model.pomdp, path)
    back = read_pomdp(path)
    original = small_hand_model.pomdp
    assert back.states == original.states and back.observations == original.observations
    for a in range(len(original.actions)):
        assert abs(back.T[a] - original.T[a]).max() < 1e-12
    assert np.allclose(back.Z, original.Z) and np.allclose(back.R, original.R)
