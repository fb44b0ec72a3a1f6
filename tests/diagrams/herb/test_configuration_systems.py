"""The configuration-estimation systems with fixed inputs, and the HERB episode of thesis
sec. 5.5 end to end."""

import json
import re
from functools import lru_cache

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from diagrams.herb.configest_episode import ConfigestEpisodeSettings, run_configest_episode
from diagrams.herb.configuration import ConfigurationEstimator, Encoders, link_polylines
from diagrams.meshcat import local_meshcat
from estimation.configuration.manifold import ProjectionManifold
from estimation.particles.factory import make_filter
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld
from models.pose import wrap_angle


@lru_cache(maxsize=1)
def two_link() -> ArmWorld:
    return ArmWorld(ArmSpec.load("2dof"))


def test_encoders_read_the_joints_through_the_offset_with_bounded_noise():
    encoders = Encoders(4, np.array([1, 2]), np.array([0.3, -0.2]), 0.05, seed=0,
                        period_s=0.1)
    context = encoders.CreateDefaultContext()
    encoders.get_input_port().FixValue(context, np.array([9.0, 1.0, 2.0, 9.0]))
    simulator = Simulator(encoders, context)
    simulator.AdvanceTo(0.35)
    reading = encoders.get_output_port().Eval(simulator.get_context())
    assert np.linalg.norm(reading - [1.3, 1.8]) <= 0.05


def test_estimator_starts_from_the_encoders_then_follows_commands_and_contact():
    world = two_link()
    estimator = ConfigurationEstimator(world, make_filter("cpf", world), particles=200,
                                       seed=0, period_s=0.1)
    context = estimator.CreateDefaultContext()
    start = np.array(world.spec.start_rad)
    estimator.GetInputPort("encoders").FixValue(context, start)
    estimator.GetInputPort("commanded").FixValue(context, start)
    estimator.GetInputPort("contact").FixValue(context, [0.0])
    np.testing.assert_allclose(estimator.GetOutputPort("mean").Eval(context), start)
    simulator = Simulator(estimator, context)
    simulator.AdvanceTo(0.05)  # the first update: the prior from the encoders
    belief = estimator.GetOutputPort("belief").Eval(simulator.get_context())
    assert len(belief) == 200
    spread = np.std(wrap_angle(np.asarray(belief.states) - start), axis=0)
    assert (spread > 1.0).all()  # the 2-DOF arm's offset sd is 2 rad
    commanded = start + [0.1, 0.0]
    estimator.GetInputPort("commanded").FixValue(simulator.get_context(), commanded)
    simulator.AdvanceTo(0.15)  # one update: every particle moved by the command
    after = np.asarray(estimator.GetOutputPort("belief").Eval(simulator.get_context()).states)
    moved = np.asarray(belief.states) + [0.1, 0.0]  # each particle, commanded
    gap = np.linalg.norm(wrap_angle(after[:, None] - moved[None]), axis=2).min(axis=1)
    assert gap.max() <= world.process_noise_radius_rad + 1e-9  # plus its motion noise
    state = simulator.get_context().get_abstract_state(0).get_value()
    np.testing.assert_allclose(state.commanded, commanded)
    assert state.contact_updates == 0


def test_ghost_arm_polylines_follow_the_chain():
    lines = link_polylines(two_link())
    assert len(lines) == 2
    np.testing.assert_allclose(lines[0][1], [0.5, 0.0, 0.0])  # the elbow, end of link 0


def test_herb_episode_writes_its_outputs(tmp_path):
    summary = run_configest_episode(ConfigestEpisodeSettings(particles=40, dual_particles=5),
                                    tmp_path, meshcat=local_meshcat(), progress=False)
    assert summary["contact_readings"] > 0
    for kind in ("cpf", "mpf-ball"):
        entry = summary["estimators"][kind]
        assert np.isfinite(entry["joint_error_rad_final"])
        assert entry["contact_updates"] == summary["contact_readings"]
    assert summary["tracking_error_rad"]["max"] < 0.1
    saved = json.loads((tmp_path / "summary.json").read_text())
    assert saved["figures"] == ["joint_error.png"]
    assert (tmp_path / "replay.html").stat().st_size > 100_000


def test_estimator_counts_and_leaves_out_non_finite_inputs():
    """NaN encoders put the start off; a NaN command holds the belief and the next finite
    one moves it the whole way; NaN readings are not weighed. Each is counted; no
    particle is ever NaN."""
    world = two_link()
    estimator = ConfigurationEstimator(world, make_filter("cpf", world), particles=100,
                                       seed=0, period_s=0.1)
    context = estimator.CreateDefaultContext()
    start = np.array(world.spec.start_rad)
    estimator.GetInputPort("encoders").FixValue(context, np.full(2, np.nan))
    estimator.GetInputPort("commanded").FixValue(context, start)
    estimator.GetInputPort("contact").FixValue(context, [0.0])
    simulator = Simulator(estimator, context)
    simulator.AdvanceTo(0.05)
    state = simulator.get_context().get_abstract_state(0).get_value()
    assert state.belief is None and state.rejected_updates == 1
    estimator.GetInputPort("encoders").FixValue(simulator.get_context(), start)
    simulator.AdvanceTo(0.15)
    first = simulator.get_context().get_abstract_state(0).get_value().belief
    assert first is not None
    estimator.GetInputPort("commanded").FixValue(simulator.get_context(), np.full(2, np.nan))
    simulator.AdvanceTo(0.25)
    held = simulator.get_context().get_abstract_state(0).get_value()
    assert held.belief is first and held.rejected_updates == 2
    estimator.GetInputPort("commanded").FixValue(simulator.get_context(), start + [0.2, 0])
    estimator.GetInputPort("contact").FixValue(simulator.get_context(), [np.nan])
    simulator.AdvanceTo(0.35)
    moved = simulator.get_context().get_abstract_state(0).get_value()
    assert moved.rejected_updates == 3 and moved.contact_updates == 0
    shift = wrap_angle(np.asarray(moved.belief.states) - np.asarray(first.states))
    assert np.isfinite(shift).all()
    assert np.allclose(np.median(shift, axis=0), [0.2, 0.0], atol=0.02)  # not resampled


def test_estimator_weighs_each_encoder_step_and_skips_a_non_finite_one():
    """With ``encoder_steps`` the estimator's update is the filter's, then the encoders'
    step weighs it (the same particles as without); a NaN reading is not weighed and the
    last finite reading is kept for the next step."""
    world = two_link()
    start = np.array(world.spec.start_rad)
    systems, simulators = [], []
    for steps in (False, True):
        system = ConfigurationEstimator(world, make_filter("cpf", world), particles=100,
                                        seed=0, period_s=0.1, encoder_steps=steps)
        context = system.CreateDefaultContext()
        system.GetInputPort("encoders").FixValue(context, start)
        system.GetInputPort("commanded").FixValue(context, start)
        system.GetInputPort("contact").FixValue(context, [0.0])
        simulator = Simulator(system, context)
        simulator.AdvanceTo(0.05)
        system.GetInputPort("commanded").FixValue(simulator.get_context(), start + [0.3, 0])
        system.GetInputPort("encoders").FixValue(simulator.get_context(), start + [0.1, 0])
        simulator.AdvanceTo(0.15)
        systems.append(system)
        simulators.append(simulator)
    plain, weighed = (s.get_context().get_abstract_state(0).get_value() for s in simulators)
    np.testing.assert_array_equal(plain.belief.states, weighed.belief.states)
    expected = world.encoder_step_log_likelihood(np.asarray(plain.belief.states),
                                                 np.array([0.3, 0.0]), np.array([0.1, 0.0]))
    np.testing.assert_allclose(weighed.belief.log_weights, expected - expected.max(), atol=1e-9)
    np.testing.assert_allclose(weighed.encoders, start + [0.1, 0])
    context = simulators[1].get_context()
    systems[1].GetInputPort("encoders").FixValue(context, np.full(2, np.nan))
    simulators[1].AdvanceTo(0.25)
    state = context.get_abstract_state(0).get_value()
    assert np.ptp(state.belief.log_weights) == 0.0  # resampled, then not weighed
    np.testing.assert_allclose(state.encoders, start + [0.1, 0])


def test_estimator_history_records_the_readings_its_filter_weighed():
    """With ``history`` the estimator keeps the readings for the MPF's exact dual density:
    a weighed reading is recorded with its command, a NaN one (not weighed) is not."""
    world = two_link()
    manifold = ProjectionManifold(world, strategy="ball", ball_radius_rad=2.0)
    estimator = ConfigurationEstimator(
        world, make_filter("mpf", world, manifold, dual_particles=5), particles=50, seed=0,
        period_s=0.1, history=True)
    context = estimator.CreateDefaultContext()
    start = np.array(world.spec.start_rad)
    estimator.GetInputPort("encoders").FixValue(context, start)
    estimator.GetInputPort("commanded").FixValue(context, start)
    estimator.GetInputPort("contact").FixValue(context, [0.0])
    simulator = Simulator(estimator, context)
    simulator.AdvanceTo(0.05)
    begun = simulator.get_context().get_abstract_state(0).get_value().history
    np.testing.assert_allclose(begun.encoders, start)
    assert len(begun.readings) == 0
    estimator.GetInputPort("commanded").FixValue(simulator.get_context(), start + [0.1, 0])
    simulator.AdvanceTo(0.15)
    estimator.GetInputPort("contact").FixValue(simulator.get_context(), [np.nan])
    simulator.AdvanceTo(0.25)
    history = simulator.get_context().get_abstract_state(0).get_value().history
    np.testing.assert_array_equal(history.readings, [[False]])
    np.testing.assert_allclose(history.commanded, [start + [0.1, 0]])


def test_episode_settings_refuse_values_out_of_range():
    """The episode's settings check themselves (not only the CLI), naming the field and
    its option."""
    for bad, message in (({"dual_particles": 100}, "dual_particles (--dual-particles)"),
                         ({"mixing_rate": -0.1}, "mixing_rate (--mixing-rate)"),
                         ({"process_noise_radius_rad": 0.6}, "(--process-noise)"),
                         ({"tactile_error_rate": float("nan")}, "(--tactile-error-rate)"),
                         ({"ball_radius_rad": 0.0}, "ball_radius_rad must be > 0"),
                         ({"seconds_per_step": -1.0}, "seconds_per_step must be > 0")):
        with pytest.raises(ValueError, match=re.escape(message)):
            ConfigestEpisodeSettings(**bad)
    assert ConfigestEpisodeSettings(tactile_error_rate=None).tactile_error_rate is None
