"""The static environment's signed distance field F(p) = SDist({p}, G_const) and its
gradient (thesis sec. 5.3), read from Drake's scene graph, evaluated two ways:

- :class:`Environment`: compiled (Numba) over any number of points, exact for the
  primitives the worlds use (sphere, box, cylinder). The thesis precomputes a voxel grid
  and differentiates it by finite differences; the primitives' closed forms are exact
  and need no grid.
- :func:`drake_signed_distance`: Drake's ``QueryObject.ComputeSignedDistanceToPoint``,
  one point at a time: the reference the vectorised path is tested against (to 1e-9 m)
  and measured against (``cmanip bench configest``). Drake's per-call cost (tens of
  microseconds per point and geometry set) is what the vectorised path avoids when a
  projection evaluates thousands of ball centres per iteration.

Signed distances are positive outside, negative inside (minus the penetration depth,
thesis eq. 5.2); gradients are unit vectors in the world frame (the direction of steepest
increase), defined everywhere (an arbitrary unit vector where the field has a kink at an
exact centre or axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from pydrake.geometry import Box, Cylinder, GeometryId, QueryObject, SceneGraphInspector, Sphere


@dataclass(frozen=True)
class Environment:
    """Obstacle primitives in the world frame.

    Attributes:
        sphere_centers: (Ns, 3) m; sphere_radii: (Ns,) m.
        box_rotations: (Nb, 3, 3) R_WB; box_centers: (Nb, 3) m; box_half: (Nb, 3) m.
        cyl_rotations: (Nc, 3, 3) R_WC (axis along the local z); cyl_centers: (Nc, 3) m;
        cyl_radii: (Nc,) m; cyl_half_lengths: (Nc,) m.
        names: the geometries' names, spheres then boxes then cylinders.
    """

    sphere_centers: np.ndarray
    sphere_radii: np.ndarray
    box_rotations: np.ndarray
    box_centers: np.ndarray
    box_half: np.ndarray
    cyl_rotations: np.ndarray
    cyl_centers: np.ndarray
    cyl_radii: np.ndarray
    cyl_half_lengths: np.ndarray
    names: tuple[str, ...]

    @staticmethod
    def from_scene_graph(inspector: SceneGraphInspector, query: QueryObject,
                         ids: list[GeometryId]) -> Environment:
        """The primitives of the geometries ``ids`` at their current world poses.

        Raises:
            ValueError: a geometry of a shape other than sphere, box or cylinder.
        """
        spheres, boxes, cylinders = [], [], []
        for gid in ids:
            shape, X = inspector.GetShape(gid), query.GetPoseInWorld(gid)
            item = (inspector.GetName(gid), X.rotation().matrix(), X.translation())
            if isinstance(shape, Sphere):
                spheres.append((*item, shape.radius()))
            elif isinstance(shape, Box):
                boxes.append((*item, shape.size() / 2))
            elif isinstance(shape, Cylinder):
                cylinders.append((*item, (shape.radius(), shape.length() / 2)))
            else:
                raise ValueError(f"obstacle geometry {inspector.GetName(gid)!r} is a "
                                 f"{type(shape).__name__}; the environment supports "
                                 f"spheres, boxes and cylinders")

        def stack(items, k, shape):
            return np.array([it[k] for it in items], dtype=float).reshape(shape)

        return Environment(
            sphere_centers=stack(spheres, 2, (-1, 3)), sphere_radii=stack(spheres, 3, (-1,)),
            box_rotations=stack(boxes, 1, (-1, 3, 3)), box_centers=stack(boxes, 2, (-1, 3)),
            box_half=stack(boxes, 3, (-1, 3)),
            cyl_rotations=stack(cylinders, 1, (-1, 3, 3)),
            cyl_centers=stack(cylinders, 2, (-1, 3)),
            cyl_radii=np.array([c[3][0] for c in cylinders], dtype=float),
            cyl_half_lengths=np.array([c[3][1] for c in cylinders], dtype=float),
            names=tuple(it[0] for it in spheres + boxes + cylinders))

    def signed_distance(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """F(p) and its gradient at points (..., 3) in the world (m).

        Returns:
            (distance (...,) m, gradient (..., 3) unit vectors in the world frame), of the
            nearest obstacle.
        """
        shape = points.shape[:-1]
        p = np.ascontiguousarray(points.reshape(-1, 3), dtype=float)
        d, g = _nearest(p, self.sphere_centers, self.sphere_radii, self.box_rotations,
                        self.box_centers, self.box_half, self.cyl_rotations,
                        self.cyl_centers, self.cyl_radii, self.cyl_half_lengths)
        return d.reshape(shape), g.reshape(*shape, 3)


@njit(cache=True)
def _rotate_into(R, c, p, out):
    """out = R^T (p - c): a world point in a primitive's frame."""
    for k in range(3):
        out[k] = R[0, k] * (p[0] - c[0]) + R[1, k] * (p[1] - c[1]) + R[2, k] * (p[2] - c[2])


@njit(cache=True)
def _rotate_out(R, g, out):
    """out = R g: a primitive-frame vector in the world."""
    for k in range(3):
        out[k] = R[k, 0] * g[0] + R[k, 1] * g[1] + R[k, 2] * g[2]


@njit(cache=True)
def _nearest(p, s_c, s_r, b_R, b_c, b_h, c_R, c_c, c_r, c_h):
    """Per point (M, 3), the nearest primitive's signed distance (M,) and world gradient
    (M, 3); compiled, a few dozen flops per point and primitive, no temporaries."""
    M = p.shape[0]
    dist = np.full(M, np.inf)
    grad = np.zeros((M, 3))
    local = np.empty(3)
    g = np.empty(3)
    for m in range(M):
        for i in range(s_r.shape[0]):
            v0, v1, v2 = p[m, 0] - s_c[i, 0], p[m, 1] - s_c[i, 1], p[m, 2] - s_c[i, 2]
            n = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            if n - s_r[i] < dist[m]:
                dist[m] = n - s_r[i]
                if n > 1e-15:
                    grad[m, 0], grad[m, 1], grad[m, 2] = v0 / n, v1 / n, v2 / n
                else:
                    grad[m, 0], grad[m, 1], grad[m, 2] = 1.0, 0.0, 0.0
        for i in range(b_h.shape[0]):
            _rotate_into(b_R[i], b_c[i], p[m], local)
            out2, inside, face = 0.0, -np.inf, 0
            for k in range(3):
                q = abs(local[k]) - b_h[i, k]
                if q > 0:
                    out2 += q * q
                if q > inside:
                    inside, face = q, k
            d = np.sqrt(out2) if out2 > 0 else inside
            if d < dist[m]:
                dist[m] = d
                for k in range(3):
                    sign = 1.0 if local[k] >= 0 else -1.0
                    if out2 > 0:
                        g[k] = sign * max(abs(local[k]) - b_h[i, k], 0.0) / d
                    else:
                        g[k] = sign if k == face else 0.0
                _rotate_out(b_R[i], g, grad[m])
        for i in range(c_r.shape[0]):
            _rotate_into(c_R[i], c_c[i], p[m], local)
            radial = np.sqrt(local[0] * local[0] + local[1] * local[1])
            dr, dz = radial - c_r[i], abs(local[2]) - c_h[i]
            out_r, out_z = max(dr, 0.0), max(dz, 0.0)
            out = np.sqrt(out_r * out_r + out_z * out_z)
            d = out if out > 0 else max(dr, dz)
            if d < dist[m]:
                dist[m] = d
                rx, ry = 1.0, 0.0
                if radial > 1e-15:
                    rx, ry = local[0] / radial, local[1] / radial
                sz = 1.0 if local[2] >= 0 else -1.0
                if out > 0:
                    g[0], g[1], g[2] = rx * out_r / out, ry * out_r / out, sz * out_z / out
                elif dr >= dz:
                    g[0], g[1], g[2] = rx, ry, 0.0
                else:
                    g[0], g[1], g[2] = 0.0, 0.0, sz
                _rotate_out(c_R[i], g, grad[m])
    return dist, grad


def drake_signed_distance(query: QueryObject, ids: set[GeometryId], point: np.ndarray
                          ) -> tuple[float, np.ndarray]:
    """Drake's F(p) over the geometries ``ids`` at one world point (3,), with its gradient
    (3,): the reference for :meth:`Environment.signed_distance`."""
    best, grad = np.inf, np.zeros(3)
    for result in query.ComputeSignedDistanceToPoint(np.asarray(point, dtype=float)):
        if result.id_G in ids and result.distance < best:
            best, grad = result.distance, np.array(result.grad_W).ravel()
    return float(best), grad
