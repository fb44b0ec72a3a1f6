"""The filters under bad inputs: non-finite actions and readings are left out and
reported, the evidence of a reading is reported, and the outlier gate passes over a
reading no state explains."""

import numpy as np
import pytest

from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
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


def test_the_outlier_gate_passes_over_a_reading_no_state_explains(world):
    """Every sensor lit while the object is 20 cm ahead: the gated CPF propagates without
    weighing and says so; the MPF's duals explain a plausible contact reading the
    particles do not, so the gate leaves that one to them."""
    belief = _belief(world, [0.2, 0.0, 0.0])
    gated = make_filter("cpf", world, outlier_log_evidence=-30.0)
    out, diag = gated.update(belief, AHEAD, np.ones(6, bool), rng=np.random.default_rng(5))
    assert diag.rejected == "outlier" and diag.log_evidence < -30.0
    assert np.ptp(out.log_weights) == 0 and not np.allclose(out.states, belief.states)
    mpf = make_filter("mpf", world, AnalyticManifold(world, dtheta_rad=np.deg2rad(5)),
                      outlier_log_evidence=-20.0)
    reading = world.sensing.true_contacts(np.array([[0.14, 0.0, 0.0]]))[0]
    assert reading.sum() >= 2  # plausible, but 5 cm from every particle
    _, diag = mpf.update(belief, AHEAD, reading, rng=np.random.default_rng(6))
    assert diag.log_evidence < -20.0 and not diag.rejected and diag.dual_used


def test_a_gate_must_be_a_negative_log_evidence(world):
    with pytest.raises(ValueError, match="outlier_log_evidence"):
        make_filter("cpf", world, outlier_log_evidence=0.5)
