"""Line-of-sight tests for the pose camera: is any part of the fiducial tag hidden by the
rods or the carriage? (seed 003's occlusions came from the robot; here they are computed
from the geometry, not drawn at random.)

A tag is visible when the segment from the camera to each of its corners misses every
occluder: vertical cylinders (the rods) and yaw-rotated boxes (the carriage plate and the
wrist). Both tests are exact for these shapes.
"""

from __future__ import annotations

import numpy as np


def tag_corners(object_pose: np.ndarray, tag_size_m: float, top_z_m: float) -> np.ndarray:
    """(4, 3) corners (m) of a square tag of side ``tag_size_m`` centred on the object's top
    face at height ``top_z_m``, turned with the object's yaw."""
    x, y, theta = object_pose
    h = tag_size_m / 2
    local = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    c, s = np.cos(theta), np.sin(theta)
    xy = local @ np.array([[c, s], [-s, c]]) + [x, y]
    return np.column_stack([xy, np.full(4, top_z_m)])


def segments_hit_vertical_cylinder(start: np.ndarray, ends: np.ndarray, axis_xy: np.ndarray,
                                   radius: float, z_range: tuple[float, float]) -> np.ndarray:
    """(E,) whether each segment ``start`` (3,) -> ``ends[e]`` (E, 3) passes within
    ``radius`` of the vertical axis at ``axis_xy`` (2,) while its height is in ``z_range``."""
    d = ends - start  # (E, 3)
    lo, hi = z_range
    with np.errstate(divide="ignore", invalid="ignore"):
        s_lo = (lo - start[2]) / d[:, 2]
        s_hi = (hi - start[2]) / d[:, 2]
    flat = np.abs(d[:, 2]) < 1e-12
    inside = (lo <= start[2]) & (start[2] <= hi)
    s0 = np.where(flat, np.where(inside, 0.0, 1.0), np.minimum(s_lo, s_hi))
    s1 = np.where(flat, np.where(inside, 1.0, 0.0), np.maximum(s_lo, s_hi))
    s0, s1 = np.clip(s0, 0.0, 1.0), np.clip(s1, 0.0, 1.0)
    rel = start[:2] - axis_xy  # (2,)
    dxy = d[:, :2]
    dd = np.einsum("ij,ij->i", dxy, dxy)
    with np.errstate(divide="ignore", invalid="ignore"):
        s_star = np.where(dd > 0, -(dxy @ rel) / dd, s0)
    s = np.clip(s_star, s0, s1)
    closest = rel + s[:, None] * dxy
    return (s1 > s0) & (np.linalg.norm(closest, axis=1) < radius)


def segments_hit_box(start: np.ndarray, ends: np.ndarray, centre: np.ndarray,
                     yaw: float, size: np.ndarray) -> np.ndarray:
    """(E,) whether each segment ``start`` -> ``ends[e]`` crosses the box of ``size`` (3,)
    centred at ``centre`` (3,) and turned by ``yaw`` about z (the slab test)."""
    c, s = np.cos(yaw), np.sin(yaw)
    R_T = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    p = R_T @ (start - centre)
    d = (ends - start) @ R_T.T  # (E, 3)
    half = np.asarray(size) / 2
    t0 = np.zeros(len(ends))
    t1 = np.ones(len(ends))
    for k in range(3):
        with np.errstate(divide="ignore", invalid="ignore"):
            a = (-half[k] - p[k]) / d[:, k]
            b = (half[k] - p[k]) / d[:, k]
        parallel = np.abs(d[:, k]) < 1e-12
        outside = (p[k] < -half[k]) | (p[k] > half[k])
        lo = np.where(parallel, np.where(outside, np.inf, -np.inf), np.minimum(a, b))
        hi = np.where(parallel, np.where(outside, -np.inf, np.inf), np.maximum(a, b))
        t0, t1 = np.maximum(t0, lo), np.minimum(t1, hi)
    return t0 <= t1


def tag_visible(camera_m: np.ndarray, corners: np.ndarray, carriage_pose: np.ndarray,
                cylinders: np.ndarray, boxes: np.ndarray, rod_bottom_z_m: float) -> bool:
    """Whether every tag corner is in the camera's line of sight.

    Args:
        camera_m: (3,) the camera's position (m).
        corners: (4, 3) the tag's corners (m).
        carriage_pose: (3,) the carriage's (x, y, yaw).
        cylinders: (C, 4) rods in the carriage frame: x, y, radius, top z (m).
        boxes: (B, 6) boxes in the carriage frame: centre xyz, size xyz (m).
        rod_bottom_z_m: height of the rods' tips (m).
    """
    cx, cy, yaw = carriage_pose
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    camera_m = np.asarray(camera_m, dtype=float)
    for x, y, radius, top in cylinders:
        axis = R @ [x, y] + [cx, cy]
        if segments_hit_vertical_cylinder(camera_m, corners, axis, radius,
                                          (rod_bottom_z_m, top)).any():
            return False
    for bx, by, bz, sx, sy, sz in boxes:
        centre = np.array([*(R @ [bx, by] + [cx, cy]), bz])
        if segments_hit_box(camera_m, corners, centre, yaw, np.array([sx, sy, sz])).any():
            return False
    return True
