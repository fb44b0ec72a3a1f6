"""Planar poses (x, y, theta) and the one angle-wrapping helper of the project."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix


def wrap_angle(angle: ArrayLike) -> np.ndarray:
    """Wrap angles (rad) to [-pi, pi). Works elementwise on arrays of any shape."""
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def planar_to_transform(x: float, y: float, theta: float, z: float = 0.0) -> RigidTransform:
    """The 3-D pose of a planar pose: translation (x, y, z) m, rotation theta rad about +z."""
    return RigidTransform(RotationMatrix.MakeZRotation(theta), [x, y, z])


def transform_to_planar(X: RigidTransform) -> np.ndarray:
    """Project a 3-D pose to (x, y, yaw); shape (3,), m and rad (yaw wrapped)."""
    yaw = RollPitchYaw(X.rotation()).yaw_angle()
    p = X.translation()
    return np.array([p[0], p[1], float(wrap_angle(yaw))])
