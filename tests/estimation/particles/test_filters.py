"""CPF, MPF and the contact-manifold representations on the planar box world."""

import numpy as np
import pytest

from estimation.hand.manifolds import RejectionSampledManifold, TrajectoryRolloutManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import (
    ConventionalParticleFilter,
    ManifoldParticleFilter,
    dual_density_ratio,
    unexplained_share,
)
from estimation.particles.kde import log_density
from estimation.particles.logmath import log_sum_exp
from models.planar.observation import observation_key

ACTION = np.array([0.005, 0.0, 0.0])
FINGERTIPS = np.array([[0.1416, 0.0, 0.0]])  # box against both fingertips


def test_analytic_samples_lie_on_the_manifold_and_explain_the_reading(box_world,
                                                                      box_manifold):
    rng = np.random.default_rng(0)
    reading = box_world.sensing.true_contacts(FINGERTIPS)[0]
    samples = box_manifold.sample(reading, 200, rng=rng)
    d = box_world.sensing.hand_distance(samples)
    assert np.all(np.abs(d) < 1e-3)
    # q(s) ~ p(o | s) on the manifold: the matching pieces carry 0.9 x their length, every
    # other piece 0.1 / 63 x its length, so some samples are (rightly) off the reading
    match = box_manifold.keys == observation_key(reading)
    share = 0.9 * box_manifold.length[match].sum() / (
        0.9 * box_manifold.length[match].sum() + 0.1 / 63 * box_manifold.length[~match].sum())
    explained = np.mean(box_world.log_likelihood(reading, samples) > np.log(0.5))
    assert abs(explained - share) < 0.1


def test_rejection_and_rollout_sets_are_near_the_hand(box_world):
    rng = np.random.default_rng(1)
    rs = RejectionSampledManifold(box_world, size=300, rng=rng)
    assert len(rs) == 300
    assert np.all(np.abs(box_world.sensing.hand_distance(rs.states)) <= 1e-3 + 1e-9)
    starts = box_world.sample_gaussian([0.2, 0.0, 0.0], [0.03, 0.03, 0.3], 60, rng=rng)
    tr = TrajectoryRolloutManifold(box_world, starts, np.array([0.01, 0, 0]), 15,
                                   per_rollout=5, rng=rng)
    assert 0 < len(tr) <= 300
    assert box_world.sensing.true_contacts(tr.states).any(axis=1).all()


def _run(filter_, world, true_start, steps, seed):
    rng = np.random.default_rng(seed)
    belief = ParticleBelief.uniform(
        world.sample_gaussian(true_start + [0.0, 0.01, 0.1], [0.02, 0.02, 0.2], 100, rng=rng))
    truth = np.array([true_start])
    diagnostics = []
    for _ in range(steps):
        truth = world.sample_step(truth, ACTION, rng=rng)
        reading = world.sample_observation(truth, rng.random((1, 2)))[0]
        belief, diag = filter_.update(belief, ACTION, reading, rng=rng)
        diagnostics.append(diag)
    return belief.rmse(truth[0]), diagnostics


def test_mpf_draws_dual_particles_during_contact_and_keeps_track(box_world, box_manifold):
    """The MPF-vs-CPF comparison is the study's (``cmanip experiment mpf``); here: the MPF
    uses its dual particles once contact is read and stays within a few cm."""
    start = np.array([0.16, 0.02, 0.05])
    for seed in range(3):
        (pos, _), diags = _run(ManifoldParticleFilter(box_world, box_manifold), box_world,
                               start, 20, seed)
        assert any(d.dual_used for d in diags)
        assert all(d.dual_used or d.sampling_failed for d in diags if d.contact_observed)
        assert pos < 0.05


def test_mixing_rate_zero_is_the_cpf_and_bad_parameters_are_refused(box_world, box_manifold):
    mpf = ManifoldParticleFilter(box_world, box_manifold, mixing_rate=0.0)
    cpf = ConventionalParticleFilter(box_world)
    a = _run(mpf, box_world, np.array([0.16, 0.0, 0.0]), 8, 3)[0]
    b = _run(cpf, box_world, np.array([0.16, 0.0, 0.0]), 8, 3)[0]
    assert a[0] == pytest.approx(b[0], abs=0.03)
    with pytest.raises(ValueError, match="mixing_rate"):
        ManifoldParticleFilter(box_world, box_manifold, mixing_rate=1.5)


def test_a_free_reading_where_every_particle_is_free_keeps_every_particle(box_world,
                                                                          box_manifold):
    """The MPF's free-space set is the conventional set restricted to free space: where
    every particle is free the two are one, and resampling their mixture must keep each
    particle once (listed twice, a tenth were dropped and a tenth copied at every free
    step, and the belief drifted between contacts)."""
    rng = np.random.default_rng(4)
    belief = ParticleBelief.uniform(box_world.sample_gaussian(
        np.array([0.4, 0.0, 0.0]), [0.01, 0.01, 0.1], 100, rng=rng))  # far from the hand
    assert not box_world.in_contact(belief.states).any()
    mpf = ManifoldParticleFilter(box_world, box_manifold, mixing_rate=0.5)
    free = np.zeros(box_world.sensor_count, bool)
    posterior, diagnostics = mpf.update(belief, np.zeros(3), free, rng=rng)
    assert not diagnostics.dual_used
    assert len(np.unique(posterior.states, axis=0)) == len(belief)


def test_density_share_keeps_phi_for_duals_where_the_posterior_is_and_cuts_far_ones():
    rng = np.random.default_rng(0)
    predicted = rng.normal(0.0, 0.1, (200, 2))
    prior_w = np.full(200, 1 / 200)
    explained = np.zeros(200)  # every conventional particle explains the reading
    cpf = np.log(prior_w)
    near = rng.normal(0.0, 0.1, (25, 2))
    far = near + 1.0  # ten prior standard deviations away

    def ratio(duals, cpf_ll=explained):
        dual_prior = log_density(duals, predicted, prior_w, angular=())
        dual_w = dual_prior - log_sum_exp(dual_prior)
        return dual_density_ratio(predicted, prior_w, (), cpf, cpf_ll, dual_w,
                                  dual_prior, rng=np.random.default_rng(1))

    assert ratio(near) > 0.5
    assert ratio(far) < 1e-6
    # where the conventional set cannot explain the reading (one wrong sensor at e = 1e-3
    # each, three of them) the duals keep much more of phi than they would otherwise
    assert ratio(near + 0.25, np.full(200, 3 * np.log(1e-3))) == 1.0
    assert ratio(near + 0.25) < 1.0
    with pytest.raises(ValueError, match="dual_share"):
        ManifoldParticleFilter(None, None, dual_share="some")


def test_evidence_share_gives_duals_what_the_prior_fails_to_explain():
    duals = np.log([0.9, 0.5, 0.1])  # the best dual explains the reading with 0.9
    assert unexplained_share(np.log(0.9), duals) == pytest.approx(0.0)
    assert unexplained_share(np.log(0.95), duals) == 0.0  # the prior explains it better
    assert unexplained_share(np.log(0.09), duals) == pytest.approx(0.9)
    assert unexplained_share(-np.inf, duals) == 1.0


def test_with_the_evidence_share_a_well_explained_reading_is_the_cpf_update(box_world,
                                                                            box_manifold):
    """A contact the prior explains as well as the manifold does gives the duals no mass
    (the fixed share gives them phi); one the prior cannot explain gets phi."""

    class Recording:
        def sample(self, observation, n, *, rng, predicted=None):
            self.duals = box_manifold.sample(observation, n, rng=rng, predicted=predicted)
            return self.duals

    def dual_share_of(posterior, recording):
        return np.isin(posterior.states[:, 0], recording.duals[:, 0]).mean()

    rng = np.random.default_rng(2)
    touching = ParticleBelief.uniform(box_world.sample_gaussian(
        FINGERTIPS[0], [0.0005, 0.0005, 0.01], 100, rng=rng))
    reading = box_world.sensing.true_contacts(FINGERTIPS)[0]
    shares = {}
    for share in ("fixed", "evidence"):
        recording = Recording()
        mpf = ManifoldParticleFilter(box_world, recording, mixing_rate=0.5, dual_share=share)
        posterior, diagnostics = mpf.update(touching, np.zeros(3), reading, rng=rng)
        assert diagnostics.dual_used
        shares[share] = dual_share_of(posterior, recording)
    assert shares["fixed"] > 0.3 and shares["evidence"] < 0.1
    far = ParticleBelief.uniform(box_world.sample_gaussian(
        np.array([0.4, 0.0, 0.0]), [0.01, 0.01, 0.1], 100, rng=rng))  # 40 cm from the hand
    recording = Recording()
    mpf = ManifoldParticleFilter(box_world, recording, mixing_rate=0.5, dual_share="evidence")
    posterior, _ = mpf.update(far, np.zeros(3), reading, rng=rng)
    assert dual_share_of(posterior, recording) > 0.3  # about phi: the prior explains nothing
