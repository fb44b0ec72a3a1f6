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


def test_a_non_finite_palm_pose_or_reading_is_left_out():
    """A NaN palm pose leaves the tracker where it was (the next finite pose moves it the
    whole way); a NaN reading is propagated through, not weighed."""
    import numpy as np

    from estimation.hand.tracker import HandRelativeTracker
    from estimation.particles.belief import ParticleBelief
    from estimation.particles.factory import make_filter
    from models.planar.world import PlanarWorld

    world = PlanarWorld.load("box", "medium")
    belief = ParticleBelief.uniform(world.sample_gaussian(
        np.array([0.3, 0.0, 0.0]), np.array([0.01, 0.01, 0.1]), 50,
        rng=np.random.default_rng(0)))
    tracker = HandRelativeTracker(belief, np.zeros(3))
    cpf = make_filter("cpf", world)
    held = tracker.update(cpf, np.array([np.nan, 0, 0]), np.zeros(6, bool),
                          rng=np.random.default_rng(1))
    assert held.belief is belief and held.last_diagnostics.rejected == "action"
    moved = held.update(cpf, np.array([0.02, 0, 0]), np.full(6, np.nan),
                        rng=np.random.default_rng(2))
    assert moved.last_diagnostics.rejected == "observation" and not moved.contact_seen
    assert np.isfinite(moved.belief.states).all()
    assert np.median(moved.belief.states[:, 0]) < 0.29  # moved by 2 cm of palm travel
