"""The exact predicted density of the static-offset model (estimation/configuration/history)."""

import numpy as np
import pytest

from estimation.configuration.history import ReadingHistory, check_dual_density
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld


@pytest.fixture(scope="module")
def world():
    return ArmWorld(ArmSpec.load("3dof"))


def test_density_is_the_prior_plus_each_reading_at_the_states_past(world):
    rng = np.random.default_rng(0)
    encoders = rng.normal(0, 0.3, world.dof)
    history = ReadingHistory.begin(encoders, np.zeros(world.dof), world.sensor_count)
    states = rng.normal(0, 0.5, (6, world.dof))
    np.testing.assert_allclose(history.log_density(world, states, np.zeros(world.dof)),
                               world.initial_log_density(encoders, states))
    commanded = [np.full(world.dof, 0.1), np.full(world.dof, 0.25)]
    readings = [np.zeros(world.sensor_count, bool), np.eye(world.sensor_count, dtype=bool)[3]]
    for c, r in zip(commanded, readings, strict=True):
        history = history.appended(c, r)
    now = np.full(world.dof, 0.4)
    expected = world.initial_log_density(encoders, world.normalise(states - now))
    for c, r in zip(commanded, readings, strict=True):
        expected = expected + world.log_likelihood(r, world.normalise(states - (now - c)))
    np.testing.assert_allclose(history.log_density(world, states, now), expected)


def test_history_needs_the_joint_metric_and_not_the_density_share():
    check_dual_density("history", "joint", "fixed")
    with pytest.raises(ValueError, match="joint metric"):
        check_dual_density("history", "kernel", "fixed")
    with pytest.raises(ValueError, match="density"):
        check_dual_density("history", "joint", "density")
    with pytest.raises(ValueError, match="dual_density"):
        check_dual_density("exact", "joint", "fixed")
