"""From a pusher log (sensor rows at the force rate) to the estimator's steps (seed 003
runs its estimate at 100 Hz, consuming forces at 250 Hz and camera poses at 30 Hz).

At each estimator time ``t_k`` a :class:`PushingSteps` row holds the latest force sample at
or before ``t_k``, and the newest camera pose that arrived in ``(t_{k-1}, t_k]``, if any.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from models.pose import wrap_angle
from models.pusher.log import PushLog

#: Seed 003 sec. V: the estimate runs at 100 Hz.
ESTIMATE_RATE_HZ = 100.0


@dataclass(frozen=True)
class PushingSteps:
    """Estimator inputs, one row per step (K rows).

    Attributes:
        t: (K,) s. rods: (K, 2, 2) rod centres (m). forces: (K, 2, 2) forces on the object
        (N). contact: (K, 2) bool, |force| >= threshold. vision_ok: (K,) bool, a new camera
        pose. vision: (K, 3) that pose (nan when none). truth: (K, 3) or nan.
        rod_radius_m: m.
    """

    t: np.ndarray
    rods: np.ndarray
    forces: np.ndarray
    contact: np.ndarray
    vision_ok: np.ndarray
    vision: np.ndarray
    truth: np.ndarray
    rod_radius_m: float

    def __len__(self) -> int:
        return len(self.t)

    def start(self, pose: np.ndarray | None = None) -> tuple[int, np.ndarray] | None:
        """Where an estimator begins: step 0 at ``pose`` if one is given, else the first
        step with a camera pose and that pose; ``None`` if the camera never saw it."""
        if pose is not None:
            return 0, np.asarray(pose, dtype=float)
        frames = np.flatnonzero(self.vision_ok)
        return (int(frames[0]), self.vision[frames[0]]) if len(frames) else None

    def inputs(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step ``k``'s rod positions, forces and contact flags."""
        return self.rods[k], self.forces[k], self.contact[k]

    def vision_at(self, k: int) -> np.ndarray | None:
        """Step ``k``'s camera pose (3,), or ``None`` without a frame."""
        return self.vision[k] if self.vision_ok[k] else None

    def estimate(self, begin, step, start: np.ndarray | None = None) -> np.ndarray:
        """Run an online estimator over these steps: ``begin(first, pose)`` starts it at
        :meth:`start`'s step and returns its estimate (3,) there; ``step(k)`` advances it
        to step ``k`` and returns the estimate. Returns (K, 3), nan before the start (or
        everywhere if the camera never saw the object and no ``start`` is given)."""
        out = np.full((len(self), 3), np.nan)
        found = self.start(start)
        if found is None:
            return out
        first, pose = found
        out[first] = begin(first, pose)
        for k in range(first + 1, len(self)):
            out[k] = step(k)
        return out

    def head(self, n: int) -> PushingSteps:
        """The first ``n`` steps."""
        return replace(self, **{f.name: getattr(self, f.name)[:n] for f in fields(self)
                                if isinstance(getattr(self, f.name), np.ndarray)})

    @staticmethod
    def from_log(log: PushLog, rate_hz: float = ESTIMATE_RATE_HZ) -> PushingSteps:
        """Resample ``log`` at ``rate_hz``; the first step is at the log's first row."""
        if rate_hz <= 0:
            raise ValueError(f"rate_hz={rate_hz} must be positive")
        times = np.arange(log.t[0], log.t[-1] + 1e-9, 1.0 / rate_hz)
        row = np.searchsorted(log.t, times + 1e-9, side="right") - 1
        # the newest frame in (t_{k-1}, t_k]: the last vision row at or before each step
        frame_rows = np.flatnonzero(log.vision_ok)
        latest = np.searchsorted(frame_rows, row, side="right") - 1
        previous_row = np.concatenate([[-1], row[:-1]])
        has = latest >= 0
        frame = np.where(has, frame_rows[np.maximum(latest, 0)], -1)
        fresh = has & (frame > previous_row)
        vision = np.full((len(times), 3), np.nan)
        vision[fresh] = log.vision[frame[fresh]]
        forces = log.forces[row]
        contact = np.linalg.norm(forces, axis=2) >= log.contact_threshold_n
        return PushingSteps(times, log.rods[row], forces, contact, fresh, vision,
                            log.truth[row], log.rod_radius_m)


def rmse(estimates: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(translation RMSE in mm, rotation RMSE in deg) of (K, 3) estimates against the truth,
    over the rows where both are finite."""
    ok = np.all(np.isfinite(estimates), axis=1) & np.all(np.isfinite(truth), axis=1)
    if not ok.any():
        return float("nan"), float("nan")
    d = estimates[ok] - truth[ok]
    translation = np.sqrt(np.mean(np.sum(d[:, :2] ** 2, axis=1))) * 1e3
    rotation = np.rad2deg(np.sqrt(np.mean(wrap_angle(d[:, 2]) ** 2)))
    return float(translation), float(rotation)
