"""Seed 003's baselines: vision only, and an extended Kalman filter with the same costs.

- **Vision only** (sec. V-A, "Baseline"): the latest camera pose, held while the camera is
  occluded.
- **EKF** (sec. V-C): the state is the pose and its covariance. The prediction is the
  stationary prior (the pose stays, with the stationary cost's covariance as process
  noise; pooled, or contact-aware like the smoother's option). The update stacks the
  step's costs as measurements of the current pose, each
  linearised once at the prediction: the motion cost with the previous pose fixed at its
  estimate, one contact cost per rod in contact, and the vision cost (its Huber weight
  evaluated at the prediction). That is what "the same measurement functions" gives a
  filter: one Gauss-Newton step per time step and no revisiting of the past, which is the
  difference the paper measures.
"""

from __future__ import annotations

import numpy as np

from estimation.pushing.costs import (
    Outline,
    contact_points,
    contact_residual,
    motion_residual,
    vision_residual,
)
from estimation.pushing.inputs import PushingSteps
from estimation.pushing.noise import PushingNoise
from models.pose import wrap_angle


def vision_only(steps: PushingSteps) -> np.ndarray:
    """(K, 3) the latest camera pose at each step (nan before the first)."""
    out = np.full((len(steps), 3), np.nan)
    frames = np.flatnonzero(steps.vision_ok)
    index = np.searchsorted(frames, np.arange(len(steps)), side="right") - 1
    have = index >= 0
    out[have] = steps.vision[frames[index[have]]]
    return out


def _retract(pose: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """First-order retraction of a local perturbation (body-frame dx, dy; dtheta)."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    moved = pose + np.array([c * xi[0] - s * xi[1], s * xi[0] + c * xi[1], xi[2]])
    moved[2] = float(wrap_angle(moved[2]))
    return moved


def _huber_weight(residual: np.ndarray, covariance: np.ndarray, k: float) -> float:
    """The Huber weight of a whitened residual's norm (1 inside ``k``)."""
    norm = float(np.sqrt(residual @ np.linalg.solve(covariance, residual)))
    return 1.0 if norm <= k else k / norm


class PushingEKF:
    """The EKF baseline (see the module docstring).

    Args:
        polygon: (V, 2) outline (m). noise: the costs' covariances. rod_radius_m: m.
        c_m: limit-surface c (m); default: the noise model's.
        contact_aware: use the noise model's contact-aware stationary covariances.
    """

    def __init__(self, polygon: np.ndarray, noise: PushingNoise, *, rod_radius_m: float,
                 c_m: float | None = None, contact_aware: bool = False):
        self.polygon = np.asarray(polygon, dtype=float)
        self.outline = Outline(self.polygon)
        self.noise = noise
        self.radius = rod_radius_m
        self.c = c_m if c_m is not None else noise.limit_surface_c(self.polygon)
        self.contact_aware = contact_aware
        self.mean: np.ndarray | None = None
        self.covariance: np.ndarray | None = None

    def start(self, pose: np.ndarray) -> None:
        self.mean = np.asarray(pose, dtype=float).copy()
        self.covariance = self.noise.vision.copy()

    def step(self, rods, forces, contact, vision, previous_inputs) -> np.ndarray:
        """One predict-update step; returns the mean (3,). ``previous_inputs`` is
        (rods, forces, contact) of the previous step (for the motion cost) or ``None``."""
        previous = self.mean.copy()
        pushed = bool(np.any(contact)) or (previous_inputs is not None
                                           and bool(np.any(previous_inputs[2])))
        P = self.covariance + self.noise.stationary_covariance(pushed, self.contact_aware)
        prior = self.mean.copy()
        rows, jacobians, blocks = [], [], []
        if previous_inputs is not None and previous_inputs[2].any():
            touching = previous_inputs[2]
            points = contact_points(previous_inputs[0][touching],
                                     previous_inputs[1][touching], self.radius)
            r, _, J = motion_residual(previous, prior, previous_inputs[1][touching], points,
                                      self.c)
            rows.append(r)
            jacobians.append(J)
            blocks.append(self.noise.motion)
        for rod in np.flatnonzero(contact):
            r, J = contact_residual(prior, rods[rod], forces[rod], self.radius, self.outline)
            rows.append(r)
            jacobians.append(J)
            blocks.append(self.noise.contact)
        if vision is not None:
            r, J = vision_residual(prior, vision)
            weight = _huber_weight(r, self.noise.vision, self.noise.vision_huber_k)
            rows.append(r)
            jacobians.append(J)
            blocks.append(self.noise.vision / weight)
        if rows:
            r = np.concatenate(rows)
            H = np.vstack(jacobians)
            noise = np.zeros((len(r), len(r)))
            at = 0
            for block in blocks:
                n = len(block)
                noise[at:at + n, at:at + n] = block
                at += n
            S = H @ P @ H.T + noise
            K = np.linalg.solve(S, H @ P).T
            self.mean = _retract(prior, -K @ r)
            P = (np.eye(3) - K @ H) @ P
        self.covariance = 0.5 * (P + P.T)
        return self.mean

    def run(self, steps: PushingSteps, *, start: np.ndarray | None = None) -> np.ndarray:
        """(K, 3) estimates, nan before the first camera pose (or from step 0 at
        ``start``)."""
        def begin(first, pose):
            self.start(pose)
            return self.mean

        return steps.estimate(begin, lambda k: self.step(*steps.inputs(k), steps.vision_at(k),
                                                         steps.inputs(k - 1)), start)
