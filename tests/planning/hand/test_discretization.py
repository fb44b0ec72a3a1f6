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


def pushed_on_axis(world, y: float = 0.0) -> np.ndarray:
    """(1, 3) the object resting against the hand's front on the lateral offset ``y`` (m),
    0.3 mm clear of it (within the sensors' 1 mm contact tolerance)."""
    lo, hi = 0.10, 0.20  # overlapping at lo, clear at hi
    for _ in range(50):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if world.overlap_free(np.array([[mid, y, 0.0]]))[0] else (mid, hi)
    return np.array([[hi + 3e-4, y, 0.0]])


def test_without_contact_states_a_cell_holds_the_poses_that_touch_the_hand():
    """The ch. 7 grid (no contact states): the cell where the bottle rests when the
    fingertips push it, in the goal on the hand's axis, has the resting poses among its
    samples, so the model keeps it (it was dropped, and the pushed bottle mapped to the
    sentinel, while the free samples avoided contact as with contact states)."""
    from models.planar.world import PlanarWorld
    from planning.hand.discretization import HandDiscretization

    world = PlanarWorld.load("bottle", sensors="fingertips", error_rate=0.0)
    pushed = pushed_on_axis(world)
    assert world.in_contact(pushed)[0]
    grid = HandDiscretization(world, HandProblemSpec.load("rel_ch7"))
    cell = grid.index(pushed)[0]
    assert cell < grid.free_count
    poses, state = grid.sample_free(50, rng=np.random.default_rng(0))
    assert world.overlap_free(poses).all()
    resting = poses[state == cell]
    assert len(resting) and world.in_contact(resting).any()
    # with contact states the resting pose has a state of its own, and free cells stay free
    split = HandDiscretization(world, HandProblemSpec.load("rel_ch7_contact"))
    assert split.is_contact_state(split.index(pushed))[0]
    poses, _ = split.sample_free(5, rng=np.random.default_rng(0))
    assert not world.in_contact(poses).any()
