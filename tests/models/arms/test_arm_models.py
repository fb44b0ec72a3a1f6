"""The arms of thesis ch. 5 as Drake plants: batched kinematics and signed distance agree
with Drake, the sensors' gradients with finite differences, bad arm files fail clearly."""

from functools import lru_cache

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from models.arms.environment import drake_signed_distance
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld, ball_points
from models.config import ConfigError
from models.pose import wrap_angle


@lru_cache(maxsize=3)
def world(arm: str) -> ArmWorld:
    return ArmWorld(ArmSpec.load(arm))


def _random_configurations(w: ArmWorld, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return w.normalise(np.array(w.spec.start_rad) + rng.normal(0.0, 0.4, (n, w.dof)))


@pytest.mark.parametrize("arm", ["2dof", "3dof", "wam"])
def test_ball_kinematics_and_signed_distance_match_drake(arm):
    w = world(arm)
    plant, scene_graph = w.model.diagram.plant(), w.model.diagram.scene_graph()
    q = _random_configurations(w, 3, seed=1)
    centres, jacobians = w.chain.centers(q, jacobian=True)
    ids = set(w.model.environment_ids)
    for k in range(len(q)):
        plant.SetPositions(w.plant_context, w.model.full_positions(q[k]))
        query = scene_graph.get_query_output_port().Eval(
            scene_graph.GetMyContextFromRoot(w.context))
        for b, ball in enumerate(w.balls):
            frame = plant.GetBodyByName(ball.link).body_frame()
            p_L = np.array(ball.center_m)[:, None]
            p_W = plant.CalcPointsPositions(w.plant_context, frame, p_L,
                                            plant.world_frame()).ravel()
            J = plant.CalcJacobianTranslationalVelocity(
                w.plant_context, JacobianWrtVariable.kQDot, frame, p_L, plant.world_frame(),
                plant.world_frame())[:, w.model.q_indices]
            np.testing.assert_allclose(centres[k, b], p_W, atol=1e-9)
            np.testing.assert_allclose(jacobians[k, b], J, atol=1e-9)
            d_drake, g_drake = drake_signed_distance(query, ids, p_W)
            d, g = w.environment.signed_distance(p_W[None])
            assert d[0] == pytest.approx(d_drake, abs=1e-9)
            np.testing.assert_allclose(g[0], g_drake, atol=1e-9)


@pytest.mark.parametrize("arm", ["3dof", "wam"])
def test_sensor_gradient_is_eq_5_4_and_matches_finite_differences(arm):
    """The analytic gradient against central differences, wherever the field is smooth:
    entries whose differences at two step sizes agree (the minimum over balls and
    obstacles has kinks, where neither is the derivative)."""
    w = world(arm)
    q = _random_configurations(w, 4, seed=2)
    _, grad = w.sensor_distances(q, gradient=True)

    def central(j, h):
        step = np.zeros(w.dof)
        step[j] = h
        return (w.sensor_distances(q + step)[0] - w.sensor_distances(q - step)[0]) / (2 * h)

    for j in range(w.dof):
        coarse, fine = central(j, 1e-5), central(j, 1e-6)
        smooth = np.abs(coarse - fine) < 1e-7
        assert smooth.mean() > 0.9
        np.testing.assert_allclose(grad[..., j][smooth], fine[smooth], atol=1e-6)


def test_projection_out_of_penetration_leaves_no_ball_inside():
    w = world("3dof")
    q = _random_configurations(w, 200, seed=3)
    free = w.project_free(q)
    assert w.ball_distances(free)[0].min() > -1e-4
    untouched = w.ball_distances(q)[0].min(axis=1) >= 0
    np.testing.assert_allclose(free[untouched], q[untouched])


def test_a_pressing_arm_sinks_as_deep_as_its_press_depth_and_no_deeper(tmp_path):
    from estimation.configuration.projection import project

    rigid = world("3dof")
    pressing = tmp_path / "pressing.yaml"
    pressing.write_text(open(rigid.spec.source).read() + "press_depth_m: 0.01\n")
    soft = ArmWorld(ArmSpec.load(pressing))
    run = soft.simulate(rng=np.random.default_rng(0))
    t = int(np.flatnonzero(run.contacts.any(axis=1))[0])
    active = np.flatnonzero(run.contacts[t])
    seeds = soft.normalise(run.q_true[t] + np.random.default_rng(1).normal(0, 0.05, (40, 3)))
    # the lit sensors on the surface, then pushed 2 cm into it along their gradient
    touching = project(rigid, seeds, active[:1]).states
    f, J = soft.sensor_distances(touching, gradient=True, sensors=active[:1])
    inside = touching - J[:, 0] * ((f[:, 0] + 0.02) / (J[:, 0] ** 2).sum(axis=1))[:, None]
    assert (soft.sensor_distances(inside, sensors=active[:1])[0] < -0.015).mean() > 0.5
    deepest = soft.ball_distances(soft.project_free(inside))[0].min(axis=1)
    assert deepest.min() > -0.01 - 1e-4 and (deepest < -0.009).mean() > 0.5
    assert rigid.ball_distances(rigid.project_free(inside))[0].min() > -1e-4
    # a sensor pressed within the depth is on the manifold of its reading
    result = project(soft, seeds, active)
    f = soft.sensor_distances(result.states[result.success], sensors=active)[0]
    assert result.success.mean() > 0.5 and (f >= -0.01 - 1e-3).all() and (f <= 1e-3).all()
    pressing.write_text(open(rigid.spec.source).read() + "press_depth_m: -0.01\n")
    with pytest.raises(ConfigError, match="press_depth_m"):
        ArmSpec.load(pressing)


def test_the_simulated_arm_touches_and_the_readings_follow_the_geometry():
    w = world("2dof")
    run = w.simulate(rng=np.random.default_rng(0))
    truth = w.true_contacts(run.q_true)
    assert truth.any(axis=1).sum() >= 20  # two touches of the point
    assert (run.contacts != truth).mean() < 0.01  # flips at the sensor error rate
    noise = np.linalg.norm(wrap_angle(run.encoders - run.q_true - run.offset), axis=1)
    assert noise.max() <= w.spec.proprio_noise_radius_rad + 1e-12


def test_ball_noise_is_inside_the_ball_and_fills_it():
    points = ball_points(np.random.default_rng(0).random((20000, 4)), 0.5)
    norms = np.linalg.norm(points, axis=1)
    assert norms.max() <= 0.5
    # uniform in a 3-ball: P(|x| < r/2) = 1/8
    assert (norms < 0.25).mean() == pytest.approx(1 / 8, abs=0.01)


def test_bad_arm_files_name_the_file_and_field(tmp_path):
    bad = tmp_path / "arm.yaml"
    bad.write_text((ArmSpec.load("wam").source and open(ArmSpec.load("wam").source).read())
                   .replace("link: wam4", "link: wam44", 1))
    with pytest.raises(ConfigError, match=r"arm\.yaml.*sensors\[forearm_0\].*wam44"):
        ArmWorld(ArmSpec.load(bad))
    bad.write_text("kind: planar\nlinks_m: [0.5, -1]\n")
    with pytest.raises(ConfigError, match=r"links_m\[1\]"):
        ArmSpec.load(bad)
    bad.write_text(open(ArmSpec.load("2dof").source).read().replace("steps: 180", "steps: 0"))
    with pytest.raises(ConfigError, match=r"trajectory\[0\]\.steps"):
        ArmSpec.load(bad)


def test_encoder_steps_weigh_where_a_contact_stopped_the_arm():
    """The encoders' step is free of the offset: out of contact every free state explains
    it alike; where the obstacle stopped the arm, the true state explains it and a state
    the command moved freely does not."""
    from estimation.configuration.proprioception import weigh_encoder_step
    from estimation.particles.belief import ParticleBelief

    w = world("3dof")
    run = w.simulate(rng=np.random.default_rng(4))
    moved = w.angle_difference(run.q_true[1:], run.q_true[:-1])
    stopped = np.linalg.norm(w.angle_difference(moved, run.commanded), axis=1)
    t = int(np.argmax(stopped))
    assert stopped[t] > 0.02
    step = w.angle_difference(run.encoders[t + 1], run.encoders[t])
    candidates = w.normalise(run.q_free[t + 1] + np.random.default_rng(6).normal(
        0.0, 0.6, (200, 3)))
    free_twice = ~w.in_contact(candidates) & ~w.in_contact(candidates - run.commanded[t])
    states = np.array([run.q_free[t + 1], candidates[np.flatnonzero(free_twice)[0]]])
    log_p = w.encoder_step_log_likelihood(states, run.commanded[t], step)
    assert log_p[0] > log_p[1] + 2  # a 0.03 rad stop against noise of sd 0.03 rad
    free = int(np.argmin(stopped))
    free_states = w.normalise(run.q_free[free + 1] + np.random.default_rng(5).normal(
        0.0, 0.01, (5, 3)))
    if not w.in_contact(free_states).any():
        free_step = w.angle_difference(run.encoders[free + 1], run.encoders[free])
        log_free = w.encoder_step_log_likelihood(free_states, run.commanded[free], free_step)
        np.testing.assert_allclose(log_free, log_free[0])
    belief = ParticleBelief.uniform(states, w.angular)
    weighed = weigh_encoder_step(w, belief, run.commanded[t], step)
    np.testing.assert_allclose(weighed.weights, np.exp(log_p) / np.exp(log_p).sum())
    assert weigh_encoder_step(w, belief, run.commanded[t], np.full(3, np.nan)) is belief
