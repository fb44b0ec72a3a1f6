"""Duals lifted from the contact surface to the commanded side (estimation/configuration/lift)."""

import numpy as np
import pytest

from estimation.configuration.lift import NormalLift, check_dual_lift, make_dual_lift
from estimation.configuration.manifold import ExplicitTwoLinkManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld

TOUCH = np.array([True])


@pytest.fixture(scope="module")
def world():
    return ArmWorld(ArmSpec.load("2dof"))


@pytest.fixture(scope="module")
def pressed(world):
    """A step of a simulated 2-DOF experiment at which the arm presses on the point: the
    true state (commanded side) and the true actual configuration, on the surface."""
    trajectory = world.simulate(rng=np.random.default_rng(0))
    gap = np.linalg.norm(world.angle_difference(trajectory.q_free, trajectory.q_true), axis=1)
    t = int(np.argmax(gap))
    assert 0.01 < gap[t] < 0.09  # pressed, by less than the lift's reach
    return trajectory.q_free[t], trajectory.q_true[t]


def test_a_surface_dual_is_lifted_to_the_pressed_state_behind_it(world, pressed):
    q_free, q_true = pressed
    lift = NormalLift(world)
    assert world.sensor_distances(q_true[None])[0][0, 0] <= world.spec.contact_tolerance_m

    def peaked(q):  # a density that knows the true state
        return -(world.angle_difference(q, q_free[None]) ** 2).sum(axis=1) / 1e-4

    lifted, log_b = lift(q_true[None], TOUCH, peaked)
    before = np.linalg.norm(world.angle_difference(q_true, q_free))
    after = np.linalg.norm(world.angle_difference(lifted[0], q_free))
    assert after < 0.25 * before  # the straight ray along the normal gets to 0.5
    np.testing.assert_allclose(log_b, peaked(lifted))
    # the lifted state is projected back to about the dual, so it reads the same contact
    back = world.project_free(lifted)
    assert np.linalg.norm(world.angle_difference(back[0], q_true)) < 0.005
    assert world.true_contacts(back)[0, 0]


def test_the_bisection_finds_a_depth_between_the_grid_points(world, pressed):
    _, q_true = pressed
    refined, grid = NormalLift(world, refine=True), NormalLift(world)
    assert refined.substeps == 4
    traced = refined.path(q_true[None], np.array([0]))
    target = traced[6, 0]  # 0.015 rad deep, halfway between two grid depths

    def peaked(q):
        return -(world.angle_difference(q, target[None]) ** 2).sum(axis=1) / 1e-4

    np.testing.assert_allclose(refined(q_true[None], TOUCH, peaked)[0][0], target)
    on_grid = grid(q_true[None], TOUCH, peaked)[0][0]
    assert any(np.allclose(on_grid, traced[i, 0]) for i in (4, 8))


def test_the_surface_is_kept_where_the_density_falls_behind_it(world, pressed):
    _, q_true = pressed
    lift = NormalLift(world)
    u = lift.directions(q_true[None], np.array([0]))

    def falling(q):  # highest in front of the surface, away from the lift's direction
        return -(world.angle_difference(q, q_true[None]) @ u[0])

    lifted, _ = lift(q_true[None], TOUCH, falling)
    np.testing.assert_allclose(lifted, q_true[None])


def test_an_identity_lift_leaves_the_filter_unchanged(world, pressed):
    q_free, _ = pressed
    manifold = ExplicitTwoLinkManifold(world)
    calls = []

    def identity(duals, observation, log_density):
        calls.append(len(duals))
        return duals, log_density(duals)

    beliefs = []
    for dual_lift in (None, identity):
        filt = make_filter("mpf", world, manifold, dual_particles=10, dual_lift=dual_lift)
        rng = np.random.default_rng(3)
        belief = ParticleBelief.uniform(q_free[None] + rng.normal(0, 0.05, (40, 2)),
                                        world.angular)
        beliefs.append(filt.update(belief, np.zeros(2), TOUCH, rng=rng)[0])
    assert calls == [10]
    np.testing.assert_array_equal(beliefs[0].states, beliefs[1].states)
    np.testing.assert_array_equal(beliefs[0].log_weights, beliefs[1].log_weights)


def test_bad_lift_settings_are_refused(world):
    check_dual_lift("normal")
    assert make_dual_lift(world, "surface") is None
    assert not make_dual_lift(world, "normal").refine
    assert make_dual_lift(world, "normal-refined").refine
    with pytest.raises(ValueError, match="dual_lift"):
        check_dual_lift("deep")
    with pytest.raises(ValueError, match="max_depth_rad"):
        NormalLift(world, max_depth_rad=0.0)


def test_a_bad_dual_lift_in_a_study_config_names_the_file_and_field(tmp_path, capsys):
    from cmanip.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text("dual_lift: deep\n")
    assert main(["experiment", "configest", "--config", str(path), "--arm", "2dof",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "dual_lift must be one of surface, normal, normal-refined" in err
    with pytest.raises(SystemExit) as exit_:  # argparse's own refusal of a bad choice
        main(["configest", "run", "--dual-lift", "deep", "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert "invalid choice: 'deep'" in capsys.readouterr().err
