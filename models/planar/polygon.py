"""Batched queries between fixed convex polygons (hand parts, sensor segments) and one convex
polygon (the object) at many poses.

Why our own and not Shapely: Shapely answers one pair at a time (or elementwise over
geometry arrays, building a geometry object per pose), and does not report penetration
depth or a contact normal. The pushing model needs all three for thousands of particles per
millimetre of travel, so the queries here work on arrays of (pose, part) pairs with numpy:

- separating-axis test (SAT) over the edge normals of both polygons: its largest separation
  is the exact signed distance when the polygons overlap (minus the penetration depth) and
  tells whether they are disjoint;
- when disjoint, the exact distance is the smallest vertex-to-edge distance either way.

A polygon with two vertices is a segment (a sensor); the same formulas hold for it.
Shapely remains the tool for unions and Minkowski boundaries (:mod:`models.planar.cspace`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from models.planar.tolerances import CONTACT_POINT_TOLERANCE_M


@dataclass(frozen=True)
class ConvexPolygons:
    """P convex polygons, padded to a common vertex count.

    Attributes:
        vertices: (P, V, 2) counter-clockwise vertices (m); shorter polygons repeat their
            last vertex.
        normals: (P, V, 2) unit outward normal of edge i (vertex i to i+1); padded edges
            repeat the previous edge's normal.
        centers: (P, 2) centre of each polygon's bounding circle (vertex mean) (m).
        radii: (P,) bounding-circle radius about ``centers`` (m).
        valid: (P, V) False for padding vertices.
        support: (P, V) largest projection of the polygon's vertices on each of its normals.
    """

    vertices: np.ndarray
    normals: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    valid: np.ndarray
    support: np.ndarray

    @staticmethod
    def from_list(polygons: list[np.ndarray]) -> ConvexPolygons:
        """Build from a list of (Vi, 2) counter-clockwise convex polygons or 2-point segments."""
        if not polygons:
            raise ValueError("need at least one polygon")
        width = max(len(p) for p in polygons)
        vertices = np.empty((len(polygons), width, 2))
        normals = np.empty_like(vertices)
        valid = np.zeros(vertices.shape[:2], dtype=bool)
        for i, poly in enumerate(polygons):
            poly = np.asarray(poly, dtype=float)
            if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 2:
                raise ValueError(f"polygon {i}: expected (V>=2, 2) vertices, got {poly.shape}")
            n = len(poly)
            vertices[i, :n] = poly
            vertices[i, n:] = poly[-1]
            valid[i, :n] = True
            edges = np.roll(poly, -1, axis=0) - poly
            lengths = np.linalg.norm(edges, axis=1)
            if np.any(lengths < 1e-12):
                raise ValueError(f"polygon {i}: repeated vertex")
            out = np.column_stack([edges[:, 1], -edges[:, 0]]) / lengths[:, None]
            normals[i, :n] = out
            normals[i, n:] = out[-1]
        centers = (vertices * valid[..., None]).sum(1) / valid.sum(1, keepdims=True)
        radii = np.linalg.norm(vertices - centers[:, None, :], axis=2).max(axis=1)
        support = _dot(normals[:, :, None, :], vertices[:, None, :, :]).max(axis=2)
        return ConvexPolygons(vertices, normals, centers, radii, valid, support)

    def __len__(self) -> int:
        return len(self.vertices)

    @cached_property
    def kernel_arrays(self) -> tuple[np.ndarray, ...]:
        """(verts, normals, support, count, centers, radii) for :mod:`models.planar.kernels`."""
        return (self.vertices, self.normals, self.support, self.valid.sum(1).astype(np.int64),
                self.centers, self.radii)

    @cached_property
    def object_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(verts, normals, support, radius about the origin) of the first polygon, as the
        object argument of the kernels."""
        n = int(self.valid[0].sum())
        verts = np.ascontiguousarray(self.vertices[0, :n])
        return (verts, np.ascontiguousarray(self.normals[0, :n]),
                np.ascontiguousarray(self.support[0, :n]),
                float(np.linalg.norm(verts, axis=1).max()))


def rotation(theta: np.ndarray) -> np.ndarray:
    """(K, 2, 2) rotation matrices of angles ``theta`` (K,) rad."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def pose_points(poses: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (V, 2) of a body at planar poses (K, 3) -> (K, V, 2) in the reference frame."""
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    x = c * points[None, :, 0] - s * points[None, :, 1] + poses[:, 0:1]
    y = s * points[None, :, 0] + c * points[None, :, 1] + poses[:, 1:2]
    return np.stack([x, y], axis=-1)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot product over the last axis (size 2), broadcasting the others.

    Written out because ``einsum`` and ``matmul`` are several times slower than two
    multiplies on these tiny trailing dimensions.
    """
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def _separations(A, nA, hA, B, nB, hB):
    """Separating-axis separations of pairs of polygons (A_m, B_m).

    Args:
        A, nA: (M, Va, 2) vertices and outward edge normals of the first polygons;
        hA: (M, Va) support of A along its own normals.
        B, nB, hB: the same for the second polygons, (M, Vb, ...).

    Returns:
        sep_a (M, Va): gap of B beyond A along A's normals; sep_b (M, Vb): gap of A beyond B
        along B's normals. The signed distance of an overlapping pair is the largest of all.
    """
    proj_b_on_na = _dot(nA[:, :, None, :], B[:, None, :, :]).min(axis=2)
    proj_a_on_nb = _dot(nB[:, :, None, :], A[:, None, :, :]).min(axis=2)
    return proj_b_on_na - hA, proj_a_on_nb - hB


def _point_edge_distance(points, starts, ends):
    """Smallest distance from each of (M, Vp, 2) points to each of (M, Ve) segments -> (M,)."""
    d = ends - starts  # (M, Ve, 2)
    length2 = np.maximum((d * d).sum(-1), 1e-18)  # (M, Ve)
    rel = points[:, :, None, :] - starts[:, None, :, :]  # (M, Vp, Ve, 2)
    t = np.clip(_dot(rel, d[:, None]) / length2[:, None], 0.0, 1.0)
    gap = rel - t[..., None] * d[:, None]
    return np.sqrt(_dot(gap, gap).min(axis=(1, 2)))


def pair_signed_distance(A, nA, hA, B, nB, hB) -> np.ndarray:
    """Exact signed distance (m) of M polygon pairs; negative = penetration depth.

    Args:
        A, nA, hA: (M, Va, 2) vertices, outward normals and (M, Va) supports;
        B, nB, hB: the same for the second polygons.

    Returns:
        (M,) signed distances.
    """
    sep_a, sep_b = _separations(A, nA, hA, B, nB, hB)
    sat = np.maximum(sep_a.max(axis=1), sep_b.max(axis=1))
    out = sat.copy()
    apart = sat > 0
    if np.any(apart):
        a, b = A[apart], B[apart]
        da = _point_edge_distance(b, a, np.roll(a, -1, axis=1))
        db = _point_edge_distance(a, b, np.roll(b, -1, axis=1))
        out[apart] = np.minimum(da, db)
    return out


def posed_object(shape: ConvexPolygons,
                 poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, normals (K, V, 2) and supports (K, V) of the polygon ``shape`` at poses."""
    vertices = pose_points(poses, shape.vertices[0])
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    n = shape.normals[0]
    normals = np.stack([c * n[None, :, 0] - s * n[None, :, 1],
                        s * n[None, :, 0] + c * n[None, :, 1]], axis=-1)
    support = shape.support[0][None] + _dot(normals, poses[:, None, :2])
    return vertices, normals, support


def candidate_pairs(parts: ConvexPolygons, shape: ConvexPolygons, poses: np.ndarray,
                    margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Broad phase: (pose, part) pairs whose bounding circles are within ``margin`` (m).

    Returns:
        ``k`` (M,), ``p`` (M,) indices of candidate pairs and the (K, P) lower bound on the
        distance from bounding circles (used for pairs that are not candidates).
    """
    center = pose_points(poses, shape.centers)[:, 0, :]  # (K, 2)
    gap = np.linalg.norm(center[:, None, :] - parts.centers[None], axis=2)
    bound = gap - parts.radii[None] - shape.radii[0]
    k, p = np.nonzero(bound <= margin)
    return k, p, bound


def signed_distances(parts: ConvexPolygons, shape: ConvexPolygons, poses: np.ndarray,
                     *, exact_within: float = 0.05, backend: str = "numba") -> np.ndarray:
    """Signed distance (m) between each part and the object at each pose.

    Args:
        parts: P fixed polygons in the reference frame.
        shape: one polygon (the object) in its body frame.
        poses: (K, 3) object poses (x m, y m, theta rad) in the reference frame.
        exact_within: pairs whose bounding circles are farther apart than this (m) get the
            bounding-circle lower bound instead of the exact distance.
        backend: ``"numba"`` (compiled, :mod:`models.planar.kernels`) or ``"numpy"`` (this
            module's array reference).

    Returns:
        (K, P) signed distances, exact wherever they are below ``exact_within``.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    if backend == "numba":
        from models.planar import kernels

        return kernels.signed_distances(np.ascontiguousarray(poses), *parts.kernel_arrays,
                                        *shape.object_arrays, float(exact_within))
    if backend != "numpy":
        raise ValueError(f"backend must be 'numba' or 'numpy', got {backend!r}")
    k, p, out = candidate_pairs(parts, shape, poses, exact_within)
    if len(k):
        rows, row = np.unique(k, return_inverse=True)
        B, nB, hB = posed_object(shape, poses[rows])
        out[k, p] = pair_signed_distance(parts.vertices[p], parts.normals[p], parts.support[p],
                                         B[row], nB[row], hB[row])
    return out


@dataclass(frozen=True)
class Penetration:
    """The deepest hand-object penetration per pose.

    Attributes:
        depth: (K,) penetration depth (m), 0 where the object does not penetrate.
        normal: (K, 2) unit direction in which the object must move to separate.
        point: (K, 2) contact point (m) in the reference frame (mean of the deepest vertices).
        part: (K,) index of the part, -1 where there is no penetration.
    """

    depth: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    part: np.ndarray


def deepest_penetration(parts: ConvexPolygons, shape: ConvexPolygons,
                        poses: np.ndarray) -> Penetration:
    """Deepest penetration of the object at each pose (K, 3) into any of the parts."""
    K = len(poses)
    depth, normal = np.zeros(K), np.zeros((K, 2))
    point, part = np.zeros((K, 2)), np.full(K, -1)
    k, p, _ = candidate_pairs(parts, shape, poses, 0.0)
    if len(k) == 0:
        return Penetration(depth, normal, point, part)
    rows, row = np.unique(k, return_inverse=True)
    B, nB, hB = posed_object(shape, poses[rows])
    B, nB, hB = B[row], nB[row], hB[row]
    A, nA = parts.vertices[p], parts.normals[p]
    sep_a, sep_b = _separations(A, nA, parts.support[p], B, nB, hB)
    sat = np.maximum(sep_a.max(axis=1), sep_b.max(axis=1))
    hit = sat < 0
    if not np.any(hit):
        return Penetration(depth, normal, point, part)
    k, p, A, nA, B, nB = k[hit], p[hit], A[hit], nA[hit], B[hit], nB[hit]
    sep_a, sep_b, sat = sep_a[hit], sep_b[hit], sat[hit]
    from_a = sep_a.max(axis=1) >= sep_b.max(axis=1)
    m = np.arange(len(k))
    # Axis of A (a hand edge): the object moves along that outward normal; its deepest
    # vertices are the contact. Axis of B (an object edge): the object moves against it; the
    # hand's deepest vertices are the contact.
    n_a = nA[m, sep_a.argmax(axis=1)]
    n_b = nB[m, sep_b.argmax(axis=1)]
    move = np.where(from_a[:, None], n_a, -n_b)
    pen_b = _dot(n_a[:, None, :], B)  # object vertices along the hand normal
    pen_a = _dot(n_b[:, None, :], A)  # hand vertices along the object normal
    mask_b = pen_b <= pen_b.min(axis=1, keepdims=True) + CONTACT_POINT_TOLERANCE_M
    mask_a = (pen_a <= pen_a.min(axis=1, keepdims=True) + CONTACT_POINT_TOLERANCE_M) & (
        parts.valid[p])
    pt_b = (B * mask_b[..., None]).sum(1) / mask_b.sum(1, keepdims=True)
    pt_a = (A * mask_a[..., None]).sum(1) / mask_a.sum(1, keepdims=True)
    contact = np.where(from_a[:, None], pt_b, pt_a)
    # Keep the deepest part per pose.
    order = np.lexsort((sat, k))  # by pose, deepest (most negative) first
    first = np.ones(len(order), dtype=bool)
    first[1:] = k[order][1:] != k[order][:-1]
    sel = order[first]
    ks = k[sel]
    depth[ks] = -sat[sel]
    normal[ks] = move[sel]
    point[ks] = contact[sel]
    part[ks] = p[sel]
    return Penetration(depth, normal, point, part)

