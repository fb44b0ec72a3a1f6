"""Batched planar rigid transforms: poses ``(x, y, theta)`` as arrays of shape (K, 3)."""

from __future__ import annotations

import numpy as np

from models.pose import wrap_angle


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose ``a * b`` (b expressed in a's frame), broadcasting (K, 3) with (K, 3) or (3,)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: np.ndarray) -> np.ndarray:
    """Inverse poses of (K, 3) or (3,) ``a``."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = -(-s * a[..., 0] + c * a[..., 1])
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def exp_twist(twist: np.ndarray) -> np.ndarray:
    """The pose reached by following a constant body twist (vx m, vy m, w rad) for unit time.

    Args:
        twist: (K, 3) displacement twists in the body frame.

    Returns:
        (K, 3) relative poses.
    """
    vx, vy, w = twist[:, 0], twist[:, 1], twist[:, 2]
    small = np.abs(w) < 1e-9
    ws = np.where(small, 1.0, w)
    sin_w = np.where(small, 1.0 - w * w / 6, np.sin(w) / ws)
    cos_w = np.where(small, w / 2, (1 - np.cos(w)) / ws)
    return np.stack([sin_w * vx - cos_w * vy, cos_w * vx + sin_w * vy, w], axis=-1)
