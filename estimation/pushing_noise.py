"""Noise models of seed 003's four costs, identified from data against ground truth.

Seed 003 sec. V-B: evaluate each cost with the sensor data and the true poses, check that
the residuals are close to normal, and take their covariance. We take the second moment
about zero, ``E[r r^T]``: a camera's calibration bias is an error the estimator cannot
remove, so it belongs in the vision cost's spread rather than being subtracted.

The defaults are the covariances this module identified on the standard procedure with
rect1 on plywood (``cmanip experiment visuotactile --part noise --trials 3 --seed 0``);
like the paper, the same covariances are then used for every object and surface.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from estimation.pushing_costs import (
    contact_residual,
    motion_residual,
    motion_terms,
    stationary_residual,
    vision_residual,
)
from estimation.pushing_inputs import PushingSteps

COSTS = ("motion", "contact", "vision", "stationary")


@dataclass(frozen=True)
class PushingNoise:
    """Covariances of the costs' residuals.

    Attributes:
        motion: (2, 2) of the motion cost (its units: N m^2, from m x N m).
        contact: (3, 3) of the contact cost (m^2).
        vision: (3, 3) of the vision cost (m^2, rad^2).
        stationary: (3, 3) of the stationary prior per estimator step (m^2, rad^2).
        vision_huber_k: the Huber threshold, in standard deviations, of the robust vision
            cost.
    """

    motion: np.ndarray = field(default_factory=lambda: np.diag([1.0e-10, 1.0e-10]))
    contact: np.ndarray = field(default_factory=lambda: np.diag([1e-6, 1e-6, 1e-6]))
    vision: np.ndarray = field(default_factory=lambda: np.diag([5e-5, 3e-5, 1.4e-3]))
    stationary: np.ndarray = field(default_factory=lambda: np.diag([2e-7, 2e-7, 2e-6]))
    vision_huber_k: float = 1.345

    def to_json(self) -> dict:
        return {name: np.asarray(getattr(self, name)).tolist() for name in COSTS} | {
            "vision_huber_k": self.vision_huber_k}

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_json(), indent=2))

    @staticmethod
    def load(path: str | Path) -> PushingNoise:
        """Read a noise file written by :meth:`save` (errors name the file and field)."""
        data = json.loads(Path(path).read_text())
        sizes = {"motion": 2, "contact": 3, "vision": 3, "stationary": 3}
        values = {}
        for name, n in sizes.items():
            if name not in data:
                raise ValueError(f"{path}: field '{name}' is missing")
            matrix = np.asarray(data[name], dtype=float)
            if matrix.shape != (n, n) or not np.all(np.linalg.eigvalsh(matrix) > 0):
                raise ValueError(f"{path}: field '{name}' must be a positive-definite "
                                 f"{n} x {n} matrix")
            values[name] = matrix
        return PushingNoise(**values, vision_huber_k=float(data.get("vision_huber_k", 1.345)))


@dataclass(frozen=True)
class Residuals:
    """Each cost's residuals at the true poses, (n, dim) per cost."""

    motion: np.ndarray
    contact: np.ndarray
    vision: np.ndarray
    stationary: np.ndarray


def residuals_at_truth(steps: PushingSteps, polygon: np.ndarray, c: float) -> Residuals:
    """Evaluate every cost the estimator would add, at the true poses."""
    truth, radius = steps.truth, steps.rod_radius_m
    motion, contact, vision, stationary = [], [], [], []
    for k in range(len(steps)):
        if steps.vision_ok[k]:
            vision.append(vision_residual(truth[k], steps.vision[k])[0])
        for rod in np.flatnonzero(steps.contact[k]):
            contact.append(contact_residual(truth[k], steps.rods[k, rod], steps.forces[k, rod],
                                            radius, polygon)[0])
        if k == 0:
            continue
        stationary.append(stationary_residual(truth[k - 1], truth[k])[0])
        touching = steps.contact[k - 1]
        if touching.any():
            _, points = motion_terms(steps.rods[k - 1, touching], steps.forces[k - 1, touching],
                                     radius)
            motion.append(motion_residual(truth[k - 1], truth[k], steps.forces[k - 1, touching],
                                          points, c)[0])

    def stack(rows, dim):
        return np.array(rows) if rows else np.zeros((0, dim))

    return Residuals(stack(motion, 2), stack(contact, 3), stack(vision, 3),
                     stack(stationary, 3))


def identify(residuals: list[Residuals], *, vision_huber_k: float = 1.345) -> PushingNoise:
    """Second moments (about zero) of the pooled residuals of several runs."""
    def moment(name, dim):
        rows = np.concatenate([getattr(r, name) for r in residuals])
        if len(rows) < dim + 1:
            raise ValueError(f"too few {name} residuals ({len(rows)}) to identify its noise")
        return rows.T @ rows / len(rows) + 1e-18 * np.eye(dim)

    return PushingNoise(moment("motion", 2), moment("contact", 3), moment("vision", 3),
                        moment("stationary", 3), vision_huber_k)
