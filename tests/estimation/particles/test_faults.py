"""The filters under bad inputs: non-finite actions and readings are left out and
reported, the evidence of a reading is reported, and the prior fallback brings a lost
belief back."""

import numpy as np
import pytest

from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from estimation.particles.recovery import PriorFallback
from models.planar.world import PlanarWorld

AHEAD = np.array([0.005, 0.0, 0.0])


@pytest.fixture(scope="module")
def world():
    return PlanarWorld.load("box", "medium")


@pytest.fixture(scope="module", params=["cpf", "mpf"])
def filt(request, world):
    if request.param == "cpf":
        return make_filter("cpf", world)
    return make_filter("mpf", world, AnalyticManifold(world, dtheta_rad=np.deg2rad(5)))


def _belief(world, mean, n=200, seed=0):
    return ParticleBelief.uniform(world.sample_gaussian(
        np.asarray(mean), np.array([0.02, 0.02, 0.2]), n, rng=np.random.default_rng(seed)))


def test_a_nan_action_skips_the_update_and_is_reported(world, filt):
    belief = _belief(world, [0.2, 0.0, 0.0])
    out, diag = filt.update(belief, np.array([np.nan, 0, 0]), np.zeros(6, bool),
                            rng=np.random.default_rng(1))
    assert diag.rejected == "action" and out is belief


def test_a_nan_reading_propagates_without_weighting_and_is_reported(world, filt):
    belief = _belief(world, [0.2, 0.0, 0.0])
    reading = np.full(6, np.nan)
    out, diag = filt.update(belief, AHEAD, reading, rng=np.random.default_rng(1))
    assert diag.rejected == "observation"
    assert np.all(np.isfinite(out.states)) and np.ptp(out.log_weights) == 0
    assert not np.allclose(out.states, belief.states)  # moved by the action


def test_the_evidence_is_the_mean_likelihood_of_the_reading(world):
    cpf = make_filter("cpf", world)
    belief = _belief(world, [0.2, 0.0, 0.0])
    rng = np.random.default_rng(2)
    predicted = world.sample_step(np.array(belief.states), AHEAD, rng=np.random.default_rng(3))
    reading = np.zeros(6, bool)
    _, diag = cpf.update(belief, AHEAD, reading, rng=np.random.default_rng(3))
    expected = np.log(np.mean(np.exp(world.log_likelihood(reading, predicted, AHEAD))))
    assert diag.log_evidence == pytest.approx(expected, abs=1e-9)
    _, surprised = cpf.update(belief, AHEAD, np.ones(6, bool), rng=rng)  # 5 cm away
    assert surprised.log_evidence < np.log(1e-3) and not surprised.rejected


def test_the_prior_fallback_brings_a_lost_belief_back(world):
    """Particles 20 cm beyond the object, which the hand reaches and pushes: every contact
    reading surprises them; after ``patience`` of them the fallback injects prior
    particles that explain the reading, and the belief's error falls."""
    rng = np.random.default_rng(4)
    truth = np.array([[0.16, 0.0, 0.0]])
    prior = world.sample_gaussian(truth[0], np.array([0.01, 0.03, 0.3]), 300, rng=rng)
    lost = _belief(world, [0.36, 0.0, 0.0], n=300)
    fallback = PriorFallback(make_filter("cpf", world), world, prior, patience=2,
                             fraction=0.3)
    plain = make_filter("cpf", world)
    belief, plain_belief = lost, lost
    injected = []
    for _ in range(12):
        truth = world.sample_step(truth, AHEAD, rng=rng)
        reading = world.sensing.true_contacts(truth)[0]
        belief, diag = fallback.update(belief, AHEAD, reading, rng=rng)
        plain_belief, _ = plain.update(plain_belief, AHEAD, reading, rng=rng)
        injected.append(diag.reinvigorated)
    assert reading.any() and max(injected) > 0 and fallback.injections >= 1
    assert belief.rmse(truth[0])[0] < 0.03 < plain_belief.rmse(truth[0])[0]


def test_bad_fallback_settings_are_refused(world):
    with pytest.raises(ValueError, match="patience"):
        PriorFallback(make_filter("cpf", world), world, np.zeros((3, 3)), patience=0)
