"""Configuration-space obstacles of the planar hand and the contact manifold's iso-contours.

For a fixed object orientation theta, the object centres at which the object overlaps a
convex hand part A form the convex polygon ``A (+) -P_o(theta)`` (Minkowski sum; seed 000
sec. 6, "Analytic Representation"). For convex polygons this is the convex hull of all
pairwise vertex differences, which we compute directly (O(Va Vo) points, tiny here); the
union over parts and its boundary come from Shapely. The boundary of the union is the
contact manifold's iso-contour ``X_c(theta)``.
"""

from __future__ import annotations

import numpy as np
import shapely

from models.planar.polygon import ConvexPolygons, rotation


def c_obstacle(parts: ConvexPolygons, outline: np.ndarray, theta: float) -> shapely.Geometry:
    """Object-centre positions (m) at which the object, rotated by ``theta`` rad, overlaps
    any part: the union of ``A (+) -P_o(theta)`` over the parts."""
    rotated = outline @ rotation(np.array([theta]))[0].T
    pieces = []
    for i in range(len(parts)):
        a = parts.vertices[i][parts.valid[i]]
        sums = (a[:, None, :] - rotated[None, :, :]).reshape(-1, 2)
        pieces.append(shapely.MultiPoint(sums).convex_hull)
    return shapely.union_all(pieces)


def contact_contour_segments(parts: ConvexPolygons, outline: np.ndarray, theta: float,
                             spacing_m: float) -> np.ndarray:
    """The iso-contour ``X_c(theta)`` as segments no longer than ``spacing_m``.

    Returns:
        (N, 2, 2) segment end points (object-centre positions, m), covering the outer
        boundary and any holes of the C-obstacle.
    """
    obstacle = c_obstacle(parts, outline, theta)
    polygons = getattr(obstacle, "geoms", [obstacle])
    out = []
    for polygon in polygons:
        for ring in [polygon.exterior, *polygon.interiors]:
            coords = np.asarray(shapely.segmentize(ring, spacing_m).coords)
            out.append(np.stack([coords[:-1], coords[1:]], axis=1))
    segments = np.concatenate(out)
    return segments[np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1) > 1e-12]
