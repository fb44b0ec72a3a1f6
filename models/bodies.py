"""Adding rigid bodies made of primitive shapes to a ``MultibodyPlant``.

The hand, objects, table and obstacles are built programmatically from their data files
(rather than through SDF text) so that shapes computed at load time, such as the extruded
polygons of seed 003's objects or the configurable tactile patches, need no files on disk.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.common import MemoryFile
from pydrake.geometry import Convex, GeometryId, InMemoryMesh, Mesh, Shape
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    RigidBody,
    SpatialInertia,
    UnitInertia,
)
from scipy.spatial import Delaunay

from models.contact import ContactMaterial


def box_inertia(mass_kg: float, size_m: Sequence[float], X_BC: RigidTransform) -> SpatialInertia:
    """Spatial inertia about the body origin of a solid box of ``size_m`` centred at ``X_BC``."""
    G = UnitInertia.SolidBox(*size_m)
    return _shifted(mass_kg, G, X_BC)


def cylinder_inertia(
    mass_kg: float, radius_m: float, length_m: float, X_BC: RigidTransform
) -> SpatialInertia:
    """Spatial inertia of a solid cylinder (axis = z of frame C) about the body origin."""
    G = UnitInertia.SolidCylinder(radius_m, length_m, [0.0, 0.0, 1.0])
    return _shifted(mass_kg, G, X_BC)


def prism_inertia(mass_kg: float, vertices_xy: np.ndarray, height_m: float) -> SpatialInertia:
    """Spatial inertia of a solid right prism over a convex polygon, about its centroid.

    Args:
        vertices_xy: (V, 2) polygon vertices (m), counter-clockwise, centroid at the origin.
        height_m: extrusion height (m), centred on z = 0.
    """
    # Second moments of the polygon area about the origin (Green's theorem).
    x, y = vertices_xy[:, 0], vertices_xy[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = cross.sum() / 2.0
    ixx_area = ((y * y + y * yn + yn * yn) * cross).sum() / 12.0  # integral of y^2
    iyy_area = ((x * x + x * xn + xn * xn) * cross).sum() / 12.0  # integral of x^2
    ixy_area = ((x * yn + 2 * x * y + 2 * xn * yn + xn * y) * cross).sum() / 24.0
    # Unit inertia of the prism (per unit mass).
    z2 = height_m**2 / 12.0
    Iyy_xx = ixx_area / area  # mean y^2
    Ixx_yy = iyy_area / area  # mean x^2
    Ixy = ixy_area / area
    G = UnitInertia(Iyy_xx + z2, Ixx_yy + z2, Ixx_yy + Iyy_xx, -Ixy, 0.0, 0.0)
    return SpatialInertia(mass_kg, np.zeros(3), G)


def _shifted(mass_kg: float, G_CCo_C: UnitInertia, X_BC: RigidTransform) -> SpatialInertia:
    M_CCo_B = SpatialInertia(mass_kg, np.zeros(3), G_CCo_C.ReExpress(X_BC.rotation()))
    return M_CCo_B.Shift(-X_BC.translation())


def prism_mesh(vertices_xy: np.ndarray, height_m: float, label: str) -> Convex:
    """A Drake ``Convex`` shape: the polygon ``vertices_xy`` (V, 2) extruded along z,
    centred on z = 0, built in memory as OBJ text."""
    v = np.asarray(vertices_xy, dtype=float)
    n = len(v)
    half = height_m / 2.0
    lines = [f"v {x:.9f} {y:.9f} {-half:.9f}" for x, y in v]
    lines += [f"v {x:.9f} {y:.9f} {half:.9f}" for x, y in v]
    lines.append("f " + " ".join(str(i + 1) for i in reversed(range(n))))  # bottom
    lines.append("f " + " ".join(str(n + i + 1) for i in range(n)))  # top
    for i in range(n):
        j = (i + 1) % n
        lines.append(f"f {i + 1} {j + 1} {n + j + 1} {n + i + 1}")
    mesh = InMemoryMesh(mesh_file=MemoryFile("\n".join(lines) + "\n", ".obj", label))
    return Convex(mesh)


def add_geometry(
    plant: MultibodyPlant,
    body: RigidBody,
    X_BG: RigidTransform,
    shape: Shape,
    name: str,
    material: ContactMaterial | None,
    rgba: Sequence[float],
) -> GeometryId | None:
    """Register a visual and (when ``material`` is given) a collision geometry on ``body``.

    Returns:
        The collision geometry's id (``None`` without a material).
    """
    collision = None
    if material is not None:
        collision = plant.RegisterCollisionGeometry(body, X_BG, shape, name,
                                                    material.proximity_properties())
    plant.RegisterVisualGeometry(body, X_BG, shape, name, np.asarray(rgba, dtype=float))
    return collision


def tessellated_prism_mesh(vertices_xy: np.ndarray, height_m: float, spacing_m: float,
                           label: str) -> Mesh:
    """A Drake ``Mesh``: the convex polygon ``vertices_xy`` (V, 2) extruded along z (centred
    on z = 0), with its top and bottom faces triangulated on a grid of ``spacing_m``.

    A rigid-hydroelastic geometry's contact surface has one polygon per triangle of its
    surface mesh, and a discrete solver applies friction at each polygon's centroid: with
    the two triangles of a coarse face, a sliding object would feel almost no frictional
    moment. A grid restores the distributed friction of a flat support (the limit
    surface's moment).
    """
    v = np.asarray(vertices_xy, dtype=float)
    boundary = []
    for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
        pieces = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing_m)))
        boundary += [a + (b - a) * k / pieces for k in range(pieces)]
    boundary = np.array(boundary)
    lo, hi = v.min(axis=0), v.max(axis=0)
    xs = np.arange(lo[0] + spacing_m / 2, hi[0], spacing_m)
    ys = np.arange(lo[1] + spacing_m / 2, hi[1], spacing_m)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    edges = np.roll(v, -1, axis=0) - v
    margin = spacing_m / 4
    lengths = np.linalg.norm(edges, axis=1)
    inside = np.all((edges[None, :, 0] * (grid[:, None, 1] - v[None, :, 1])
                     - edges[None, :, 1] * (grid[:, None, 0] - v[None, :, 0]))
                    / lengths[None, :] > margin, axis=1)
    points = np.vstack([boundary, grid[inside]])
    triangles = Delaunay(points).simplices
    a, b, c = (points[triangles[:, i]] for i in range(3))
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    triangles = np.where((area > 0)[:, None], triangles, triangles[:, ::-1])  # all CCW
    n, nb = len(points), len(boundary)
    half = height_m / 2
    lines = [f"v {x:.9f} {y:.9f} {-half:.9f}" for x, y in points]
    lines += [f"v {x:.9f} {y:.9f} {half:.9f}" for x, y in points]
    lines += [f"f {i + 1} {k + 1} {j + 1}" for i, j, k in triangles]  # bottom, facing -z
    lines += [f"f {n + i + 1} {n + j + 1} {n + k + 1}" for i, j, k in triangles]  # top
    for i in range(nb):  # boundary points come first, counter-clockwise
        j = (i + 1) % nb
        lines.append(f"f {i + 1} {j + 1} {n + j + 1}")
        lines.append(f"f {i + 1} {n + j + 1} {n + i + 1}")
    return Mesh(InMemoryMesh(mesh_file=MemoryFile("\n".join(lines) + "\n", ".obj", label)))
