"""Constraint projection onto the implicit contact manifold, the seeding strategies, the
explicit 2-DOF manifold, and the MPF running on them (thesis sec. 5.1-5.2)."""

from functools import lru_cache

import numpy as np
import pytest

from estimation.configuration.manifold import (
    ExplicitTwoLinkManifold,
    ProjectionManifold,
    union_of_balls,
)
from estimation.configuration.projection import EPS_PROJ_M, project
from estimation.particles.belief import ParticleBelief
from estimation.particles.kde import log_density
from experiments.configest_study import ConfigestSettings, run_filter
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld


@lru_cache(maxsize=3)
def world(arm: str) -> ArmWorld:
    return ArmWorld(ArmSpec.load(arm))


@pytest.mark.parametrize("method", ["gd", "lm"])
@pytest.mark.parametrize("arm", ["3dof", "wam"])
def test_projected_samples_lie_on_the_manifold(arm, method):
    w = world(arm)
    run = w.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    active = np.flatnonzero(run.contacts[t])
    seeds = w.normalise(run.q_true[t] + np.random.default_rng(1).normal(0, 0.1, (60, w.dof)))
    result = project(w, seeds, active, method=method)
    assert result.success.mean() > 0.5
    f, _ = w.sensor_distances(result.states[result.success], sensors=active)
    assert np.abs(f).max() <= EPS_PROJ_M
    f_failed, _ = w.sensor_distances(result.states[~result.success], sensors=active)
    assert (np.abs(f_failed).max(axis=1) > EPS_PROJ_M).all()


@pytest.mark.parametrize("arm", ["3dof", "wam"])
def test_full_projection_also_keeps_the_unlit_sensors_clear_and_the_body_out(arm):
    w = world(arm)
    run = w.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    active = np.flatnonzero(run.contacts[t])
    seeds = w.normalise(run.q_true[t] + np.random.default_rng(1).normal(0, 0.1, (60, w.dof)))
    thesis = project(w, seeds, active, constraints="active")
    full = project(w, seeds, active, constraints="full")
    assert full.success.mean() > 0.3
    ok = full.states[full.success]
    f, _ = w.sensor_distances(ok, sensors=active)
    assert np.abs(f).max() <= EPS_PROJ_M
    unlit = np.setdiff1d(np.arange(w.sensor_count), active)
    clear, _ = w.sensor_distances(ok, sensors=unlit)
    assert (clear > w.spec.contact_tolerance_m).all()
    body, _ = w.ball_distances(ok, balls=np.flatnonzero(w.sensor_of_ball < 0))
    assert (body >= -EPS_PROJ_M).all()
    # every accepted sample reads exactly the observation; eq. 5.1 alone does not ensure it
    assert (w.true_contacts(ok) == run.contacts[t]).all()
    loose = thesis.states[thesis.success]
    assert (w.log_likelihood(run.contacts[t], ok) >= w.log_likelihood(
        run.contacts[t], loose).max() - 1e-9).all()
    with pytest.raises(ValueError, match="constraint set"):
        project(w, seeds, active, constraints="some")


def test_explicit_manifold_holds_exactly_the_elbow_up_and_down_configurations():
    w = world("2dof")
    explicit = ExplicitTwoLinkManifold(w)
    point = explicit.center + np.array([0.01, 0.0])
    q = explicit.configurations(np.array([point, point]), np.array([True, False]))
    assert q[0, 1] > 0 > q[1, 1]  # the two branches
    tips, _ = w.chain.centers(q, balls=np.array([0]))
    np.testing.assert_allclose(tips[:, 0, :2], [point, point], atol=1e-12)
    draws = explicit.sample(np.array([True]), 500, rng=np.random.default_rng(0))
    distance, _ = w.sensor_distances(draws)
    np.testing.assert_allclose(distance, 0.0, atol=1e-9)  # the tip ball touches the point
    assert explicit.sample(np.array([False]), 5, rng=np.random.default_rng(0)).shape == (0, 2)


def test_union_of_balls_is_uniform_over_the_union():
    centers = np.array([[0.0, 0.0], [0.5, 0.0]])  # overlapping discs of radius 0.5
    points = union_of_balls(centers, 0.5, 40000, rng=np.random.default_rng(0), wrap=False)
    covered = (np.linalg.norm(points[:, None] - centers[None], axis=2) <= 0.5).sum(axis=1)
    assert covered.min() >= 1
    # the lens where the discs overlap: its share of the union's area
    lens = 2 * 0.25 * np.arccos(0.5) - 0.25 * np.sqrt(4 * 0.25 - 0.25)
    union = 2 * np.pi * 0.25 - lens
    assert (covered == 2).mean() == pytest.approx(lens / union, abs=0.01)


def test_scaled_balls_are_ellipsoids_of_half_axes_radius_times_scale():
    centers = np.array([[0.0, 0.0], [1.0, 1.0]])
    scale = np.array([0.1, 1.0])
    points = union_of_balls(centers, 2.0, 5000, rng=np.random.default_rng(0), wrap=False,
                            scale=scale)
    whitened = np.linalg.norm((points[:, None] - centers[None]) / scale, axis=2)
    assert whitened.min(axis=1).max() <= 2.0
    spread = np.abs(points - centers[np.argmin(whitened, axis=1)])
    assert spread[:, 0].max() <= 0.2 < 1.5 < spread[:, 1].max()


def test_the_kernel_metric_reaches_the_manifold_by_the_wide_joints():
    """Projection in the metric diag(scale)^-2 lands on the manifold and moves the seeds
    less, measured in that metric, than the joint-space projection does."""
    w = world("wam")
    run = w.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    active = np.flatnonzero(run.contacts[t])
    rng = np.random.default_rng(1)
    scale = np.array([0.3, 0.02, 0.3, 0.02, 0.3, 0.3, 0.02])
    seeds = w.normalise(run.q_true[t] + rng.normal(0, 1, (60, w.dof)) * scale)
    moved = {}
    for name, metric in (("joint", None), ("kernel", scale)):
        result = project(w, seeds, active, scale=metric)
        assert result.success.mean() > 0.5
        ok = result.success
        f, _ = w.sensor_distances(result.states[ok], sensors=active)
        assert np.abs(f).max() <= EPS_PROJ_M
        moved[name] = np.linalg.norm((result.states[ok] - seeds[ok]) / scale, axis=1)
    assert np.median(moved["kernel"]) < 0.5 * np.median(moved["joint"])


def test_kernel_metric_ball_draws_stay_near_the_prior():
    w = world("3dof")
    run = w.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    prior = ParticleBelief.uniform(w.normalise(
        run.q_true[t] + np.random.default_rng(2).normal(0, 1, (100, 3)) * [0.3, 0.05, 0.05]),
        w.angular)
    density = {}
    for metric in ("joint", "kernel"):
        manifold = ProjectionManifold(w, strategy="ball", metric=metric)
        draws = manifold.sample(run.contacts[t], 25, rng=np.random.default_rng(3),
                                predicted=prior)
        assert len(draws) > 0
        density[metric] = np.median(log_density(draws, prior.states, prior.weights,
                                                angular=prior.angular))
    assert density["kernel"] > density["joint"]
    with pytest.raises(ValueError, match="ball_radius_rad"):
        ProjectionManifold(w, metric="kernel", ball_radius_rad=0.1)
    with pytest.raises(ValueError, match="metric"):
        ProjectionManifold(w, metric="bogus")


@pytest.mark.parametrize("strategy", ["uniform", "particle", "ball"])
def test_each_strategy_draws_contact_states_and_counts_its_failures(strategy):
    w = world("3dof")
    run = w.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    prior = ParticleBelief.uniform(
        w.normalise(run.q_true[t] + np.random.default_rng(2).normal(0, 0.1, (100, 3))),
        w.angular)
    manifold = ProjectionManifold(w, strategy=strategy)
    draws = manifold.sample(run.contacts[t], 25, rng=np.random.default_rng(3),
                            predicted=prior)
    assert 0 < len(draws) <= 25
    active = np.flatnonzero(run.contacts[t])
    assert np.abs(w.sensor_distances(draws, sensors=active)[0]).max() <= EPS_PROJ_M
    assert manifold.stats.seeds >= 25 and manifold.stats.draws == 1
    assert 0.0 <= manifold.stats.failure_rate < 1.0
    with pytest.raises(ValueError, match="strategy"):
        ProjectionManifold(w, strategy="bogus")


def test_the_mpf_finds_the_2dof_arm_more_often_than_the_cpf():
    """Thesis Fig. 5.3a, H1: over four seeded runs, after the two touches the MPF's final
    error is below the CPF's, which collapses onto whatever its particles first explained."""
    w = world("2dof")
    settings = ConfigestSettings(arms=("2dof",), trials=2)
    finals = {"cpf": [], "mpf-ball": []}
    for seed in range(4):
        run = w.simulate(rng=np.random.default_rng((seed, 0)))
        for kind in finals:
            rmse = run_filter(w, run, kind, settings,
                              rng=np.random.default_rng((seed, 1))).rmse_rad
            finals[kind].append(rmse[-1])
    assert np.mean(finals["mpf-ball"]) < np.mean(finals["cpf"]) - 0.5
    assert min(finals["mpf-ball"]) < 0.1  # on the truth when it finds it
