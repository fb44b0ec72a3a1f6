"""The pure tactile functions: per-patch forces and the thesis' noise model."""

import numpy as np
import pytest

from models.herb.tactile import SensorGroups, TactileLayout, TactileNoise, patch_force_magnitudes


def test_forces_sum_per_patch_and_ignore_non_patches():
    forces = patch_force_magnitudes(
        np.array([0, 0, 2, -1]),
        np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, 3.0], [100.0, 0, 0]]),
        num_patches=3,
    )
    np.testing.assert_allclose(forces, [np.sqrt(5.0), 0.0, 3.0])


def test_no_contact_pairs_gives_zero_forces():
    np.testing.assert_array_equal(patch_force_magnitudes([], np.zeros((0, 3)), 4), np.zeros(4))


def test_noiseless_readings_threshold_the_force():
    contact, _ = TactileNoise.noiseless(0.5).sample(np.array([0.0, 0.4, 0.6, 2.0]),
                                                     rng=np.random.default_rng(0))
    np.testing.assert_array_equal(contact, [False, False, True, True])


def test_default_noise_is_the_thesis_model():
    noise = TactileNoise()
    rng = np.random.default_rng(1)
    trials = 20000
    # Hand touching nothing: perfectly discriminative, never a false positive.
    free, _ = noise.sample(np.zeros((trials, 5)), rng=rng)
    assert not free.any()
    # In contact (patch 0 touching): every reading is wrong 10% of the time.
    forces = np.zeros((trials, 5))
    forces[:, 0] = 3.0
    contact, _ = noise.sample(forces, rng=rng)
    wrong = np.concatenate([~contact[:, 0], contact[:, 1:].ravel()])
    assert wrong.mean() == pytest.approx(0.1, abs=0.01)


def test_sampling_is_reproducible_from_the_seed():
    forces = np.abs(np.random.default_rng(2).normal(size=(50, 6)))
    a = TactileNoise().sample(forces, rng=np.random.default_rng(9))
    b = TactileNoise().sample(forces, rng=np.random.default_rng(9))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_invalid_rates_rejected():
    with pytest.raises(ValueError, match="false_negative_rate"):
        TactileNoise(false_negative_rate=1.5)


def test_distal_links_layout_makes_every_distal_face_a_patch():
    layout = TactileLayout.load("distal_links")
    assert layout.patch_names == tuple(f"{f}_{p}" for f in ("f1", "f2", "f3")
                                       for p in ("tip", "distal_0", "distal_outer"))


def test_sensor_groups_pool_the_patches_of_each_finger_side():
    names = TactileLayout.load("distal_links").patch_names
    membership = SensorGroups().membership(names)
    assert membership.shape == (2, 9)
    np.testing.assert_array_equal(membership.sum(axis=1), [6, 3])
    assert membership[1, names.index("f3_distal_outer")] == 1
    with pytest.raises(ValueError, match="pool no patch"):
        SensorGroups().membership(("f1_tip", "palm_0"))
