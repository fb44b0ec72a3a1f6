"""Particle beliefs, low-variance resampling, RMSE, KDE."""

import numpy as np
import pytest

from estimation.particles.belief import ParticleBelief, low_variance_indices
from estimation.particles.kde import (
    leave_one_out_log_density,
    log_density,
    silverman_bandwidth,
)
from models.pose import wrap_angle


def test_low_variance_resampling_keeps_proportions():
    rng = np.random.default_rng(0)
    w = np.array([0.5, 0.25, 0.125, 0.125])
    counts = np.bincount(low_variance_indices(w, 800, rng=rng), minlength=4)
    assert list(counts) == [400, 200, 100, 100]  # systematic: exact for these weights


def test_rmse_and_mean_handle_the_angle_wrap():
    belief = ParticleBelief(np.array([[0.0, 0.0, np.pi - 0.1], [0.0, 0.0, -np.pi + 0.1]]),
                            np.log([0.5, 0.5]))
    pos, ang = belief.rmse(np.array([0.03, 0.04, np.pi]))
    assert np.isclose(pos, 0.05) and np.isclose(ang, 0.1)
    assert np.isclose(abs(belief.mean()[2]), np.pi)


def test_belief_is_immutable_and_all_minus_infinity_means_uniform():
    belief = ParticleBelief(np.zeros((3, 3)), np.full(3, -np.inf))
    assert np.allclose(belief.weights, 1 / 3)
    try:
        belief.states[0, 0] = 1.0
    except ValueError:
        pass
    else:
        raise AssertionError("states must be read-only")


def test_kde_integrates_to_one_and_wraps_orientation():
    rng = np.random.default_rng(1)
    centres = np.column_stack([rng.normal(0, 0.01, 200), rng.normal(0, 0.02, 200),
                               np.pi - 0.02 + rng.normal(0, 0.3, 200)])
    w = np.ones(200)
    h = silverman_bandwidth(centres, w)
    box = np.array([[-0.08, -0.15, -np.pi], [0.08, 0.15, np.pi]])
    q = box[0] + (box[1] - box[0]) * rng.random((200_000, 3))
    volume = np.prod(box[1] - box[0])
    integral = np.exp(log_density(q, centres, w, h)).mean() * volume
    assert abs(integral - 1.0) < 0.08
    across = log_density(np.array([[0, 0, -np.pi + 0.02]]), centres, w, h)
    same = log_density(np.array([[0, 0, np.pi - 0.02]]), centres, w, h)
    assert np.isclose(across, same, atol=1.0)  # 4 cm of arc apart across the wrap: close


def test_effective_sample_size_and_weighted_mean():
    states = np.array([[0.0, 0.0, 0.0], [0.1, 0.2, np.pi / 2]])
    belief = ParticleBelief(states, np.log([0.75, 0.25]))
    assert np.isclose(belief.effective_sample_size(), 1 / (0.75**2 + 0.25**2))
    mean = belief.mean()
    assert np.allclose(mean[:2], [0.025, 0.05])
    assert np.isclose(mean[2], np.arctan2(0.25, 0.75))


def test_a_seven_joint_belief_declares_its_angular_columns():
    rng = np.random.default_rng(3)
    q = rng.normal(0.0, 0.1, (200, 7))
    q[:, 6] += np.pi  # the last joint straddles the wrap-around
    belief = ParticleBelief.uniform(q, angular=(6,))
    mean = belief.mean()
    assert mean.shape == (7,)
    np.testing.assert_allclose(mean[:6], q[:, :6].mean(axis=0))
    assert abs(abs(mean[6]) - np.pi) < 0.05
    true = np.zeros(7)
    true[6] = -np.pi
    linear, angular = belief.rmse(true)
    assert abs(angular - np.sqrt(np.mean(wrap_angle(q[:, 6] + np.pi) ** 2))) < 1e-12
    assert abs(linear - np.sqrt(np.mean((q[:, :6] ** 2).sum(1)))) < 1e-12
    resampled = belief.resample(50, rng=rng)
    assert resampled.angular == (6,) and resampled.states.shape == (50, 7)


def test_angular_columns_must_be_columns_of_the_state():
    with pytest.raises(ValueError, match="angular columns"):
        ParticleBelief.uniform(np.zeros((4, 2)))


def test_leave_one_out_density_leaves_out_exactly_the_point_itself():
    rng = np.random.default_rng(3)
    states, weights = rng.normal(size=(40, 3)), rng.random(40)
    h = np.array([0.5, 0.7, 0.9])
    idx = np.array([0, 7, 39])
    loo = leave_one_out_log_density(idx, states, weights, h, angular=())
    for k, i in enumerate(idx):
        others = np.delete(np.arange(40), i)
        direct = log_density(states[i:i + 1], states[others], weights[others], h, angular=())
        # the others' density, scaled by their share of the total weight
        expected = direct[0] + np.log(weights[others].sum() / weights.sum())
        assert loo[k] == pytest.approx(expected, abs=1e-9)
    lonely = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    assert np.isneginf(leave_one_out_log_density(np.array([0]), lonely, np.ones(2), h,
                                                 angular=()))[0]
