"""The compiled kernels give the numpy reference's answers."""

import numpy as np
import pytest

from models.planar.world import PlanarWorld


@pytest.fixture(scope="module")
def numpy_world():
    return PlanarWorld.load("box", "medium", backend="numpy")


def test_pushing_kernel_matches_the_numpy_reference(box_world, numpy_world):
    rng = np.random.default_rng(3)
    states = box_world.sample_gaussian([0.17, 0.0, 0.0], [0.03, 0.06, 1.5], 400, rng=rng)
    action = np.array([0.02, 0.0, 0.05])
    u = rng.random((400, box_world.uniforms_per_step(action)))
    compiled = box_world.step(states, action, u)
    reference = numpy_world.step(states, action, u)
    assert np.abs(compiled - reference).max() < 1e-9
    assert np.abs(compiled - states).max() > 0.01  # something was pushed


def test_distance_kernel_matches_the_numpy_reference(box_world, numpy_world):
    rng = np.random.default_rng(4)
    states = np.column_stack([rng.uniform(0.0, 0.25, 2000), rng.uniform(-0.15, 0.15, 2000),
                              rng.uniform(-np.pi, np.pi, 2000)])
    assert np.array_equal(box_world.sensing.true_contacts(states),
                          numpy_world.sensing.true_contacts(states))
    a, b = box_world.sensing.hand_distance(states), numpy_world.sensing.hand_distance(states)
    near = np.minimum(a, b) < 1e-3
    assert near.sum() > 50 and np.abs(a[near] - b[near]).max() < 1e-12
