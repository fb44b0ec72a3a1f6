"""Binary contact observations: readings, noise statistics, likelihood."""

import numpy as np

from models.planar.observation import observation_key, observation_keys, observation_reading


def test_no_false_positive_in_free_space_and_ten_percent_errors_in_contact(box_world):
    rng = np.random.default_rng(0)
    free = np.tile([[0.4, 0.0, 0.0]], (4000, 1))
    assert not box_world.sample_observation(free, rng.random((4000, 2))).any()
    touching = np.tile([[0.1416, 0.0, 0.0]], (4000, 1))  # against both fingertips
    truth = box_world.sensing.true_contacts(touching[:1])[0]
    assert truth.sum() == 2  # the two fingertip sensors
    readings = box_world.sample_observation(touching, rng.random((4000, 2)))
    wrong = np.mean(~(readings == truth).all(axis=1))
    assert abs(wrong - 0.1) < 0.02


def test_log_likelihood_of_matching_wrong_and_impossible_readings(box_world):
    states = np.array([[0.1416, 0.0, 0.0], [0.4, 0.0, 0.0]])
    truth = box_world.sensing.true_contacts(states[:1])[0]
    ll = box_world.log_likelihood(truth, states)
    assert np.isclose(ll[0], np.log(0.9)) and ll[1] == -np.inf
    none = np.zeros_like(truth)
    ll = box_world.log_likelihood(none, states)
    assert np.isclose(ll[0], np.log(0.1 / (2 ** len(truth) - 1))) and ll[1] == 0.0


def test_observation_keys_agree():
    obs = np.array([[True, False, True], [False, False, False]])
    assert list(observation_keys(obs)) == [observation_key(obs[0]), 0] == [5, 0]


def test_observation_readings_invert_their_keys():
    for key in range(8):
        reading = observation_reading(key, 3)
        assert reading.dtype == bool and observation_key(reading) == key
