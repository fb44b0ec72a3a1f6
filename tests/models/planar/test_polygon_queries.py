"""Batched convex-polygon queries against Shapely, pair by pair."""

import numpy as np
import shapely

from models.planar.polygon import (
    ConvexPolygons,
    deepest_penetration,
    pose_points,
    signed_distances,
)

SQUARE = np.array([[-0.02, -0.02], [0.02, -0.02], [0.02, 0.02], [-0.02, 0.02]])
TRIANGLE = np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.03]])
HEXAGON = 0.03 * np.column_stack([np.cos(np.arange(6) * np.pi / 3),
                                  np.sin(np.arange(6) * np.pi / 3)])


def test_signed_distance_matches_shapely():
    rng = np.random.default_rng(0)
    parts = ConvexPolygons.from_list([SQUARE + [0.05, 0.0], TRIANGLE - [0.05, 0.02]])
    shape = ConvexPolygons.from_list([HEXAGON])
    poses = np.column_stack([rng.uniform(-0.12, 0.12, 400), rng.uniform(-0.08, 0.08, 400),
                             rng.uniform(-np.pi, np.pi, 400)])
    d = signed_distances(parts, shape, poses, exact_within=1.0)
    posed = pose_points(poses, HEXAGON)
    overlaps = 0
    for k in range(len(poses)):
        obj = shapely.Polygon(posed[k])
        for p, verts in enumerate([SQUARE + [0.05, 0.0], TRIANGLE - [0.05, 0.02]]):
            part = shapely.Polygon(verts)
            if obj.intersects(part) and obj.intersection(part).area > 1e-12:
                overlaps += 1
                assert d[k, p] < 0
                # minus the depth: the smallest translation that separates them is no
                # longer than the object's extent
                assert -d[k, p] <= 0.1
            else:
                assert abs(d[k, p] - obj.distance(part)) < 1e-9
    assert overlaps > 10


def test_penetration_depth_and_normal_of_a_known_overlap():
    parts = ConvexPolygons.from_list([SQUARE])
    shape = ConvexPolygons.from_list([SQUARE])
    # the object overlaps the part by 5 mm along +x, squarely: face contact
    pen = deepest_penetration(parts, shape, np.array([[0.035, 0.0, 0.0], [0.5, 0.0, 0.0]]))
    assert np.isclose(pen.depth[0], 0.005)
    assert np.allclose(pen.normal[0], [1.0, 0.0])
    assert np.isclose(pen.point[0, 1], 0.0, atol=1e-9)  # mid-face, by symmetry
    assert pen.part[1] == -1 and pen.depth[1] == 0.0


def test_segments_are_polygons_too():
    segment = ConvexPolygons.from_list([np.array([[0.0, -0.05], [0.0, 0.05]])])
    shape = ConvexPolygons.from_list([SQUARE])
    d = signed_distances(segment, shape, np.array([[0.03, 0.0, 0.0], [0.0, 0.0, 0.3]]),
                         exact_within=1.0)
    assert np.isclose(d[0, 0], 0.01)
    assert d[1, 0] < 0  # crossing the square
