"""The trust-region discretisation: cells, contact pieces, the sentinel, and sampling."""

import numpy as np
import pytest

from planning.hand.discretization import HandProblemSpec, symmetry_order


def test_symmetry_orders():
    rectangle = np.array([[-2, -1], [2, -1], [2, 1], [-2, 1]], dtype=float)
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
    kite = np.array([[-1, 0], [0, -1], [2, 0], [0, 1]], dtype=float)
    assert symmetry_order(rectangle) == 2
    assert symmetry_order(square) == 4
    assert symmetry_order(kite) == 1


def test_the_box_needs_fifteen_orientation_bins(small_hand_model):
    disc = small_hand_model.discretization
    assert disc.period_rad == pytest.approx(np.pi)
    assert disc.theta_bins == 15  # 180 deg / 12 deg, as the thesis' 2625 = 7 x 25 x 15
    assert disc.shape_xy == (11, 8)


def test_free_cell_centres_map_to_their_own_cell(small_hand_model):
    disc = small_hand_model.discretization
    poses = disc.representative_poses()[:disc.free_count]
    free = ~small_hand_model.world.in_contact(poses)
    index = disc.index(poses[free])
    assert np.array_equal(index, np.flatnonzero(free))


def test_samples_stay_in_their_state(small_hand_model):
    disc = small_hand_model.discretization
    rng = np.random.default_rng(1)
    poses, state = disc.sample_free(3, rng=rng)
    assert np.array_equal(disc.index(poses), state)
    assert not small_hand_model.world.in_contact(poses).any()
    poses, state = disc.sample_contact(3, rng=rng)
    assert disc.is_contact_state(state).all()
    assert small_hand_model.world.in_contact(poses).all()
    assert np.array_equal(disc.index(poses), state)


def test_outside_the_trust_region_is_the_sentinel(small_hand_model):
    disc = small_hand_model.discretization
    poses = np.array([[0.5, 0.0, 0.0], [0.1, 0.3, 1.0], [-0.05, 0.0, 0.0]])
    assert (disc.index(poses) == disc.sentinel).all()
    assert (small_hand_model.index(poses) == small_hand_model.sentinel).all()


def test_contact_pieces_are_at_most_a_centimetre(small_hand_model):
    disc = small_hand_model.discretization
    for contour in disc.contours:
        assert contour.length_m / contour.count <= disc.spec.contact_cell_m + 1e-12


def test_spec_rejects_bad_values():
    with pytest.raises(ValueError, match="trust_x_m"):
        HandProblemSpec(trust_x_m=(0.0, 0.01))
    with pytest.raises(ValueError, match="discount"):
        HandProblemSpec(discount=1.0)


def test_spec_file_errors_name_the_field(tmp_path, refused):
    path = tmp_path / "problem.yaml"
    path.write_text("trust_x_m: [0.0, 0.5]\ntrust_y_m: [-0.075, 0.075]\n")
    spec = HandProblemSpec.load(path)
    assert spec.trust_x_m == (0.0, 0.5) and spec.trust_y_m == (-0.075, 0.075)
    refused(HandProblemSpec.load, "discount: 1.5\n", "discount")
    refused(HandProblemSpec.load, "trust_region: 3\n", "trust_region")
