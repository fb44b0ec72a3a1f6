"""The TactileSensor LeafSystem in isolation (fixed inputs, no diagram)."""

import numpy as np
import pytest
from pydrake.geometry import GeometryId
from pydrake.multibody.plant import ContactResults

from diagrams.tactile_sensor import TactileSensor
from models.herb.tactile import SensorGroups, TactileLayout, TactileNoise

LAYOUT = TactileLayout.load("fingertips")


def make_sensor(noise):
    geometry = {name: GeometryId.get_new_id() for name in LAYOUT.patch_names}
    return TactileSensor(LAYOUT, geometry, noise=noise, seed=3, period_s=0.01)


def update(sensor, time_s=0.0):
    context = sensor.CreateDefaultContext()
    context.SetTime(time_s)
    sensor.get_input_port().FixValue(context, ContactResults())
    state = sensor.EvalUniquePeriodicDiscreteUpdate(context)
    context.SetDiscreteState(state.get_vector().value())
    return (sensor.GetOutputPort("contact").Eval(context),
            sensor.GetOutputPort("force").Eval(context))


def test_no_contact_reads_nothing():
    contact, force = update(make_sensor(TactileNoise()))
    np.testing.assert_array_equal(contact, np.zeros(3))
    assert np.all(force >= 0.0) and force.max() < 0.5


def test_false_positive_path_reaches_the_outputs():
    always_wrong = TactileNoise(false_positive_rate_free=1.0, force_noise_std_n=0.0)
    contact, force = update(make_sensor(always_wrong))
    np.testing.assert_array_equal(contact, np.ones(3))
    np.testing.assert_array_equal(force, np.zeros(3))


def test_noise_is_a_function_of_seed_and_time_only():
    coin = TactileNoise(false_positive_rate_free=0.5)
    first = [update(make_sensor(coin), t)[0] for t in (0.0, 0.01, 0.02, 0.03)]
    again = [update(make_sensor(coin), t)[0] for t in (0.0, 0.01, 0.02, 0.03)]
    np.testing.assert_array_equal(first, again)
    assert len({tuple(c) for c in first}) > 1


def test_missing_patch_geometry_is_an_error():
    with pytest.raises(ValueError, match="no geometry for patches"):
        TactileSensor(LAYOUT, {"f1_tip": GeometryId.get_new_id()})


def test_pooled_sensors_draw_their_own_noise():
    """Groups get one draw each: a group never reads more errors than one sensor would."""
    geometry = {name: GeometryId.get_new_id() for name in LAYOUT.patch_names}
    always_wrong = TactileNoise(false_positive_rate_free=1.0, force_noise_std_n=0.0)
    sensor = TactileSensor(LAYOUT, geometry, noise=always_wrong, seed=3,
                           groups=SensorGroups())
    context = sensor.CreateDefaultContext()
    sensor.get_input_port().FixValue(context, ContactResults())
    context.SetDiscreteState(sensor.EvalUniquePeriodicDiscreteUpdate(context).get_vector()
                             .value())
    np.testing.assert_array_equal(sensor.GetOutputPort("sensor_contact").Eval(context),
                                  [1.0, 1.0])
    assert sensor.GetOutputPort("force").size() == 3
