"""The planar hand: projected from the Drake hand, sensors on its front."""

import numpy as np
import pytest

from models.planar.hand import PlanarHand, PlanarSensorLayout


@pytest.mark.parametrize("layout, count", [("low", 3), ("medium", 6), ("high", 12)])
def test_layouts_put_equal_length_sensors_across_the_front(layout, count):
    hand = PlanarHand.load(layout)
    assert hand.sensor_count == count
    assert set(hand.sensor_of_segment) == set(range(count))
    lengths = np.zeros(count)
    np.add.at(lengths, hand.sensor_of_segment,
              np.linalg.norm(hand.sensor_segments[:, 1] - hand.sensor_segments[:, 0], axis=1))
    assert np.allclose(lengths, lengths.mean(), rtol=1e-6)
    # ordered from the F1/F2 side (-y) to F3 (+y), mirror-symmetric about the centre line
    mids = hand.sensor_segments.mean(axis=1)
    first, last = mids[hand.sensor_of_segment == 0], mids[hand.sensor_of_segment == count - 1]
    assert first[:, 1].mean() < 0 < last[:, 1].mean()
    assert np.isclose(first[:, 1].mean(), -last[:, 1].mean(), atol=1e-6)
    # everything on the front lies ahead of the palm (the fingers' outer faces and tips)
    assert hand.sensor_segments[..., 0].min() > 0.06


def test_hand_dimensions_follow_the_hand_file():
    hand = PlanarHand.load("medium")
    verts = hand.parts.vertices.reshape(-1, 2)
    # fingertips: proximal 70 mm from a joint 4 mm behind the palm, distal 60 mm at 42 deg
    reach = -0.004 + 0.070 + 0.060 * np.cos(0.733) + 0.009 * np.sin(0.733)
    assert np.isclose(verts[:, 0].max(), reach, atol=1e-3)
    assert np.isclose(verts[:, 1].max(), 0.060, atol=1e-3)  # F3 knuckle housing edge


def test_bad_layout_file_names_the_field(refused):
    refused(PlanarSensorLayout.load, "front_sensors: 0\n", "front_sensors")


def test_front_layout_needs_its_sensor_count_and_links_layout_has_five(refused):
    refused(PlanarSensorLayout.load, "min_facing: 0.1\n",
            "'front_sensors': required field is missing")
    refused(PlanarSensorLayout.load, "kind: links\nfront_sensors: 3\n",
            "'front_sensors': a links layout has one sensor per")
    assert PlanarSensorLayout.load("links").front_sensors == 5
