"""The lattice of palm poses in the table plane (thesis sec. 7.1, eq. 7.1).

The palm moves at a fixed height above the table with a fixed orientation, so a lattice
point is a planar palm pose ``X_r = start * Trans(ix dx, iy dy)`` with integer ``(ix, iy)``
in the hand's start frame: x forward along the palm's heading, y to its left. The thesis'
lattice also has an angular resolution ``2 pi / n_theta``; its ch. 7 problem uses only
translations (four 1 cm templates), so this lattice has one orientation, the start's, and
a template that turns the hand is refused.

Points are numbered row-major over a rectangle ``ix in [x_min, x_max]``,
``iy in [y_min, y_max]``; a template is an integer step ``(dix, diy)``, and the neighbour
table (P, A) gives each point's successor under each template (-1 off the lattice).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from models.se2 import compose, inverse


@dataclass(frozen=True)
class LatticeSpec:
    """Where the lattice lies and how fine it is.

    Attributes:
        start: (x m, y m, theta rad) the palm's start pose in the world; lattice point
            (0, 0). Its theta is every point's orientation.
        resolution_m: dx = dy, the spacing of the points (m; thesis: 1 cm).
        x_range_m: (back, forward) extent of the lattice along the start heading, relative
            to the start (m).
        y_range_m: (right, left) extent across it (m).
    """

    start: tuple[float, float, float]
    resolution_m: float = 0.01
    x_range_m: tuple[float, float] = (-0.10, 0.40)
    y_range_m: tuple[float, float] = (-0.40, 0.40)

    def __post_init__(self):
        if not 0.001 <= self.resolution_m <= 0.1:
            raise ValueError(f"resolution_m must be in [0.001, 0.1] m, got {self.resolution_m}")
        for name in ("x_range_m", "y_range_m"):
            lo, hi = getattr(self, name)
            if not lo <= 0.0 <= hi:
                raise ValueError(f"{name} must contain 0 (the start), got {(lo, hi)}")

    @cached_property
    def bounds(self) -> tuple[int, int, int, int]:
        """(x_min, x_max, y_min, y_max) integer indices."""
        r = self.resolution_m
        return (int(np.ceil(self.x_range_m[0] / r - 1e-9)),
                int(np.floor(self.x_range_m[1] / r + 1e-9)),
                int(np.ceil(self.y_range_m[0] / r - 1e-9)),
                int(np.floor(self.y_range_m[1] / r + 1e-9)))

    @property
    def shape(self) -> tuple[int, int]:
        """(nx, ny) points along and across the start heading."""
        x0, x1, y0, y1 = self.bounds
        return x1 - x0 + 1, y1 - y0 + 1

    @property
    def size(self) -> int:
        """P, the number of lattice points."""
        nx, ny = self.shape
        return nx * ny

    def point(self, ix: np.ndarray | int, iy: np.ndarray | int) -> np.ndarray:
        """Index of the point (ix, iy) (integer offsets from the start; -1 off the lattice)."""
        x0, x1, y0, y1 = self.bounds
        ix, iy = np.asarray(ix), np.asarray(iy)
        inside = (ix >= x0) & (ix <= x1) & (iy >= y0) & (iy <= y1)
        return np.where(inside, (ix - x0) * self.shape[1] + (iy - y0), -1)

    @property
    def start_point(self) -> int:
        return int(self.point(0, 0))

    def offsets(self, points: np.ndarray | int) -> tuple[np.ndarray, np.ndarray]:
        """(ix, iy) of point indices."""
        x0, _, y0, _ = self.bounds
        points = np.asarray(points)
        return points // self.shape[1] + x0, points % self.shape[1] + y0

    def poses(self, points: np.ndarray | int) -> np.ndarray:
        """(..., 3) planar world palm poses (m, m, rad) of point indices."""
        ix, iy = self.offsets(points)
        r = self.resolution_m
        local = np.stack([ix * r, iy * r, np.zeros(np.shape(ix))], axis=-1)
        return compose(np.asarray(self.start, dtype=float), local)

    def nearest_point(self, pose: np.ndarray) -> tuple[int, float]:
        """The lattice point nearest the planar world pose (3,) (-1 when that is off the
        lattice), and the pose's distance (m) from it."""
        local = compose(inverse(np.asarray(self.start, dtype=float)), np.asarray(pose)[:3])
        steps = np.round(local[:2] / self.resolution_m)
        distance = float(np.hypot(*(local[:2] - steps * self.resolution_m)))
        return int(self.point(int(steps[0]), int(steps[1]))), distance

    def template_steps(self, action_vectors: np.ndarray) -> np.ndarray:
        """(A, 2) integer lattice steps of hand-frame action vectors (A, 3) (m, m, rad).

        Raises:
            ValueError: a template that turns the hand, or does not end on a lattice point.
        """
        vectors = np.asarray(action_vectors, dtype=float)
        if np.any(np.abs(vectors[:, 2]) > 1e-12):
            raise ValueError("the lattice has one orientation: action templates may not turn "
                             f"the hand, got {vectors[:, 2].tolist()} rad")
        steps = vectors[:, :2] / self.resolution_m
        rounded = np.round(steps)
        if np.any(np.abs(steps - rounded) > 1e-6):
            raise ValueError(f"action templates {vectors[:, :2].tolist()} m do not end on "
                             f"the {self.resolution_m} m lattice")
        return rounded.astype(np.int64)

    def neighbours(self, action_vectors: np.ndarray) -> np.ndarray:
        """(P, A) the successor of every point under every template (-1 off the lattice)."""
        steps = self.template_steps(action_vectors)
        ix, iy = self.offsets(np.arange(self.size))
        return np.stack([self.point(ix + dx, iy + dy) for dx, dy in steps], axis=1)
