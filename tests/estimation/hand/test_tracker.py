"""Tracking the hand-relative belief from the measured hand motion."""

import numpy as np

from estimation.hand.tracker import HandRelativeTracker
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import ConventionalParticleFilter
from models.planar.world import PlanarWorld


def _far_belief(n=200, seed=0):
    rng = np.random.default_rng(seed)
    states = np.column_stack([rng.uniform(0.30, 0.35, n), rng.uniform(-0.05, 0.05, n),
                              rng.uniform(-np.pi, np.pi, n)])
    return ParticleBelief.uniform(states)


def test_far_objects_stay_put_in_the_world_while_the_hand_moves():
    world = PlanarWorld.load("small_box", "fingertips")
    hand = np.array([0.6, -0.2, np.pi / 2])  # facing world +y
    initial = _far_belief()
    tracker = HandRelativeTracker(initial, hand)
    before = tracker.world_poses()
    moved = hand + np.array([0.0, 0.01, 0.0])  # 1 cm forward
    start = tracker
    tracker = tracker.update(ConventionalParticleFilter(world), moved, np.zeros(2, dtype=bool),
                             rng=np.random.default_rng(1))
    assert start.updates == 0 and start.belief is initial  # a value: the old one stands
    # 1 cm nearer in the hand frame, give or take the resampling
    assert abs(tracker.belief.mean()[0] - (initial.mean()[0] - 0.01)) < 2e-3
    after = tracker.world_poses()
    # the resampled particles are a subset of the old ones, at the same world poses
    matches = np.isclose(after[:, None, :2], before[None, :, :2], atol=1e-9).all(axis=2)
    assert matches.any(axis=1).all()
    assert tracker.updates == 1 and not tracker.contact_seen


def test_a_contact_reading_is_remembered():
    world = PlanarWorld.load("small_box", "fingertips")
    hand = np.zeros(3)
    cpf = ConventionalParticleFilter(world)
    tracker = HandRelativeTracker(_far_belief(), hand)
    tracker = tracker.update(cpf, hand, np.array([True, False]), rng=np.random.default_rng(2))
    tracker = tracker.update(cpf, hand, np.array([False, False]), rng=np.random.default_rng(3))
    assert tracker.contact_seen and tracker.updates == 2
    assert tracker.last_diagnostics is not None and not tracker.last_diagnostics.contact_observed
