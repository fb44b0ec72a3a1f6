"""The configuration lattice: IK points, lazy edges with collision checks, the disk cache."""

import numpy as np
import pytest

from models.herb.kinematics import PlanarHandIK
from planning.lattice.grid import LatticeSpec
from planning.lattice.ik_table import cache_key, load_ik_table, surface_scene
from planning.lattice.lattice import UNKNOWN, ConfigurationLattice

FORWARD, BACK, LEFT, RIGHT = range(4)


def test_grid_indices_poses_and_neighbours(small_spec, moves):
    assert small_spec.shape == (5, 5) and small_spec.size == 25
    start = small_spec.start_point
    np.testing.assert_allclose(small_spec.poses(start), small_spec.start)
    neighbours = small_spec.neighbours(moves)
    ahead = neighbours[start, FORWARD]
    np.testing.assert_allclose(small_spec.poses(ahead)[:2],
                               np.array(small_spec.start[:2]) + [0.02, 0.0])
    assert neighbours[ahead, BACK] == start
    corner = int(small_spec.point(2, 2))  # forward-left corner: nothing further
    assert neighbours[corner, FORWARD] == -1 and neighbours[corner, LEFT] == -1
    with pytest.raises(ValueError, match="do not end on"):
        small_spec.template_steps(np.array([[0.015, 0, 0]]))
    with pytest.raises(ValueError, match="may not turn"):
        small_spec.template_steps(np.array([[0.02, 0, 0.1]]))


def test_ik_points_reproduce_their_palm_poses(wall, small_spec, small_table):
    fk = PlanarHandIK(surface_scene(wall))
    assert small_table.reachable.all()
    for point in range(small_spec.size):
        x, y, theta, z = fk.palm_pose(small_table.q[point])
        target = small_spec.poses(point)
        assert np.hypot(x - target[0], y - target[1]) < 2e-4
        assert abs(theta - target[2]) < 2e-3
        assert z == pytest.approx(fk.world.palm_height_m, abs=2e-4)
    neighbours = small_spec.neighbours(np.array([[0.02, 0, 0], [0, 0.02, 0]]))
    steps = np.abs(small_table.q[neighbours[neighbours[:, 0] >= 0, 0]]
                   - small_table.q[neighbours[:, 0] >= 0]).max()
    assert steps < 0.2  # seeded from a neighbour: 2 cm apart, close in joint space


def test_the_ik_table_is_cached_on_disk_by_robot_table_and_lattice(wall, small_spec,
                                                                   tmp_path):
    first = load_ik_table(wall, small_spec, cache_dir=tmp_path, progress=False)
    (path,) = (tmp_path / "lattice").glob("*.npz")
    assert path.stem == first.key == cache_key(wall, small_spec)
    again = load_ik_table(wall, small_spec, cache_dir=tmp_path, progress=False)
    np.testing.assert_array_equal(again.q, first.q)
    # obstacles are not part of the key; the table, the height and the lattice are
    assert cache_key(surface_scene(wall), small_spec) == first.key
    finer = LatticeSpec(start=small_spec.start, resolution_m=0.01, x_range_m=(0, 0.02),
                        y_range_m=(0, 0.02))
    assert cache_key(wall, finer) != first.key


def test_an_edge_into_the_wall_is_infeasible_and_one_away_from_it_feasible(
        wall, small_table, moves):
    lattice = ConfigurationLattice(wall, small_table, moves)
    start = lattice.start_point
    right = lattice.edge(start, RIGHT)
    assert not right.feasible and "wall" in right.reason
    back = lattice.edge(start, BACK)
    assert back.feasible and back.reason == ""
    assert back.q.shape[1] == 7 and len(back.q) >= 2
    np.testing.assert_allclose(back.q[0], small_table.q[start])
    np.testing.assert_allclose(back.q[-1], small_table.q[back.target])
    # the palm follows the template's straight motion, within the tolerance
    assert np.abs(back.poses[:, 1] - back.poses[0, 1]).max() < lattice.path_tolerance_m
    # clearance from Drake's signed distance: positive in free space, the wall closest
    # the signed-distance clearance agrees with the collision checker's verdicts
    assert lattice.checker.GetLargestPadding() < lattice.clearance(start, BACK) <= 0.1
    into_wall = small_table.q[lattice.neighbours[start, RIGHT]]  # its end collides
    assert lattice.kinematics.min_distance(into_wall) < lattice.checker.GetLargestPadding()
    assert np.isnan(lattice.clearance(start, RIGHT))  # no path was built
    edge_off = lattice.edge(int(lattice.spec.point(-2, 0)), BACK)
    assert not edge_off.feasible and "leaves the lattice" in edge_off.reason


def test_evaluation_is_lazy_and_kept(wall, small_table, moves):
    lattice = ConfigurationLattice(wall, small_table, moves)
    assert (lattice.status == UNKNOWN).all()
    start = lattice.start_point
    answer = lattice.feasible(np.array([start, start]), np.array([BACK, BACK]))
    stats = lattice.stats()
    assert answer.all() and stats.edges_evaluated == 1 and stats.points_evaluated == 2
    assert stats.edge_fraction == pytest.approx(1 / (25 * 4))
    assert lattice.asked.sum() == 1
    evaluated = lattice.evaluated_edges()
    lattice.reset_asked()
    lattice.feasible(np.array([start]), np.array([BACK]))  # answered from what is kept
    assert lattice.evaluated_edges() == evaluated and lattice.asked.sum() == 1
    assert lattice.feasible_actions(start).tolist() == [True, True, True, False]
    assert lattice.stats().edges_evaluated == 4
