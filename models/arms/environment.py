"""The static environment's signed distance field F(p) = SDist({p}, G_const) and its
gradient (thesis sec. 5.3), read from Drake's scene graph, evaluated two ways:

- :class:`Environment`: vectorised numpy over any number of points, exact for the
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
        p = points.reshape(-1, 3)
        dist, grad = [], []
        if len(self.sphere_radii):
            d, g = _sphere(p, self.sphere_centers, self.sphere_radii)
            dist.append(d)
            grad.append(g)
        if len(self.box_half):
            d, g = _box(p, self.box_rotations, self.box_centers, self.box_half)
            dist.append(d)
            grad.append(g)
        if len(self.cyl_radii):
            d, g = _cylinder(p, self.cyl_rotations, self.cyl_centers, self.cyl_radii,
                             self.cyl_half_lengths)
            dist.append(d)
            grad.append(g)
        d = np.concatenate(dist, axis=1)  # (M, obstacles)
        g = np.concatenate(grad, axis=1)  # (M, obstacles, 3)
        nearest = np.argmin(d, axis=1)
        rows = np.arange(len(p))
        return d[rows, nearest].reshape(shape), g[rows, nearest].reshape(*shape, 3)


def _unit(v: np.ndarray, norm: np.ndarray) -> np.ndarray:
    """v / |v| with (1, 0, 0) where |v| = 0."""
    fallback = np.zeros(v.shape[-1])
    fallback[0] = 1.0
    safe = np.where(norm > 1e-15, norm, 1.0)[..., None]
    return np.where(norm[..., None] > 1e-15, v / safe, fallback)


def _sphere(p, centers, radii):
    v = p[:, None, :] - centers[None]
    n = np.linalg.norm(v, axis=-1)
    return n - radii[None], _unit(v, n)


def _box(p, rotations, centers, half):
    local = np.einsum("bji,mbj->mbi", rotations, p[:, None, :] - centers[None])
    q = np.abs(local) - half[None]
    outside_v = np.maximum(q, 0.0)
    outside = np.linalg.norm(outside_v, axis=-1)
    inside = np.minimum(q.max(-1), 0.0)
    sign = np.where(local >= 0, 1.0, -1.0)
    g_out = sign * outside_v / np.where(outside > 0, outside, 1.0)[..., None]
    face = np.argmax(q, axis=-1)
    g_in = np.zeros_like(local)
    np.put_along_axis(g_in, face[..., None], np.take_along_axis(sign, face[..., None], -1),
                      axis=-1)
    g_local = np.where((outside > 0)[..., None], g_out, g_in)
    return outside + inside, np.einsum("bij,mbj->mbi", rotations, g_local)


def _cylinder(p, rotations, centers, radii, half_lengths):
    local = np.einsum("bji,mbj->mbi", rotations, p[:, None, :] - centers[None])
    radial = np.linalg.norm(local[..., :2], axis=-1)
    d = np.stack([radial - radii[None], np.abs(local[..., 2]) - half_lengths[None]], -1)
    outside_v = np.maximum(d, 0.0)
    outside = np.linalg.norm(outside_v, axis=-1)
    inside = np.minimum(d.max(-1), 0.0)
    r_hat = _unit(np.concatenate([local[..., :2], np.zeros_like(radial)[..., None]], -1),
                  radial)
    z_hat = np.zeros_like(local)
    z_hat[..., 2] = np.where(local[..., 2] >= 0, 1.0, -1.0)
    g_out = (r_hat * outside_v[..., :1] + z_hat * outside_v[..., 1:]) / np.where(
        outside > 0, outside, 1.0)[..., None]
    g_in = np.where((d[..., 0] >= d[..., 1])[..., None], r_hat, z_hat)
    g_local = np.where((outside > 0)[..., None], g_out, g_in)
    return outside + inside, np.einsum("bij,mbj->mbi", rotations, g_local)


def drake_signed_distance(query: QueryObject, ids: set[GeometryId], point: np.ndarray
                          ) -> tuple[float, np.ndarray]:
    """Drake's F(p) over the geometries ``ids`` at one world point (3,), with its gradient
    (3,): the reference for :meth:`Environment.signed_distance`."""
    best, grad = np.inf, np.zeros(3)
    for result in query.ComputeSignedDistanceToPoint(np.asarray(point, dtype=float)):
        if result.id_G in ids and result.distance < best:
            best, grad = result.distance, np.array(result.grad_W).ravel()
    return float(best), grad
