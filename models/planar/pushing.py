"""Quasi-static pushing by the planar hand (Lynch, Maekawa, Tanie 1992), batched over
particles, as the thesis' transition model (Koval 2016, sec. 3.1 and 4.3.1).

Model (``shared/reference/pushing_and_sensing.md``): ellipsoidal limit surface with
``c = m_max / f_max``; a point contact at ``r`` (object frame, about the centre of
friction = the footprint centroid) with inward normal ``n``; the hand point's velocity
``vp``. Separation when ``vp . n <= 0``; sticking when ``vp`` lies inside the motion cone
(twist ``V = ((c^2 + x^2) vpx + x y vpy, x y vpx + (c^2 + y^2) vpy, x vpy - y vpx) / D``,
``D = c^2 + x^2 + y^2``); otherwise sliding along the nearer cone edge.

Stepping (penetration-based, as the thesis' simulator): the hand advances ``step_m`` (1 mm)
at a time. After each advance the object, still where it was in the world, may overlap the
hand. The deepest overlap gives a contact point, normal and depth; Lynch's model gives the
direction of the object's motion for the hand point's velocity there, and the motion is
scaled so that the contact point moves out by exactly the depth. Several simultaneous
contacts (a box squarely against two fingertips, an object wedged against a finger) are
resolved by repeating this for the deepest remaining overlap, up to
``contact_iterations`` times per step (a projected Gauss-Seidel sweep over contacts, each
using the single-contact model). When a push is tangent or separating but the object
still overlaps (possible only after a sweep was cut short) the object is translated out
along the normal. ``tests/models/planar/test_pushing.py`` checks the sticking/sliding
boundary for continuity and the leftover overlap; ``experiments/push_validation.py``
compares whole pushes with Drake's hydroelastic simulation.

Uncertainty (sec. 4.3.1): before every step the finger-object friction ``mu ~ N(0.5,
0.2^2)`` and the pressure-distribution radius ``c ~ N(0.05 m, (0.01 m)^2)`` are drawn,
truncated to positive values. They are drawn by inverse CDF from caller-supplied uniforms,
so a step is deterministic given its uniforms (DESPOT scenarios replay exactly).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

from models.planar.polygon import ConvexPolygons, deepest_penetration
from models.planar.tolerances import OVERLAP_TOLERANCE_M
from models.se2 import compose, exp_twist, inverse


@dataclass(frozen=True)
class PushingParameters:
    """Parameters of the pushing model (thesis sec. 4.3.1 defaults).

    Attributes:
        step_m: hand travel per physics step (m).
        mu_mean, mu_std: finger-object friction coefficient distribution (truncated > 0).
        c_mean_m, c_std_m: limit-surface radius ``c = m_max / f_max`` distribution (m).
        contact_iterations: overlap resolutions per step (for simultaneous contacts).
    """

    step_m: float = 0.001
    mu_mean: float = 0.5
    mu_std: float = 0.2
    c_mean_m: float = 0.05
    c_std_m: float = 0.01
    contact_iterations: int = 6

    def __post_init__(self):
        if self.step_m <= 0 or self.contact_iterations < 1:
            raise ValueError("step_m must be > 0 and contact_iterations >= 1")
        if self.mu_mean <= 0 or self.c_mean_m <= 0 or self.mu_std < 0 or self.c_std_m < 0:
            raise ValueError("mu and c need positive means and non-negative deviations")


def truncated_normal(u: np.ndarray, mean: float, std: float) -> np.ndarray:
    """Inverse CDF of N(mean, std^2) truncated to (0, inf) at uniforms ``u`` in [0, 1)."""
    if std == 0:
        return np.full_like(u, mean, dtype=float)
    low = ndtr(-mean / std)
    p = np.clip(low + u * (1.0 - low), 1e-12, 1 - 1e-12)
    return np.maximum(mean + std * ndtri(p), 1e-9)


def lynch_twist(r: np.ndarray, n: np.ndarray, vp: np.ndarray, mu: np.ndarray,
                c: np.ndarray) -> np.ndarray:
    """Object twist for a point push, in the object frame (Lynch et al. 1992).

    Args:
        r: (K, 2) contact point (m) relative to the centre of friction.
        n: (K, 2) unit inward normal of the object at the contact (the push direction).
        vp: (K, 2) velocity of the hand point at the contact (m per unit time).
        mu: (K,) friction coefficient; c: (K,) limit-surface radius (m).

    Returns:
        (K, 3) twist (vx, vy, w) whose contact point moves with the pusher when sticking
        and has the pusher's normal velocity when sliding; zero when separating.
    """
    c2 = c * c
    x, y = r[:, 0], r[:, 1]
    D = c2 + x * x + y * y
    stick = np.stack([((c2 + x * x) * vp[:, 0] + x * y * vp[:, 1]) / D,
                      (x * y * vp[:, 0] + (c2 + y * y) * vp[:, 1]) / D,
                      (x * vp[:, 1] - y * vp[:, 0]) / D], axis=-1)
    alpha = np.arctan(mu)
    edges = []
    for sign in (+1.0, -1.0):  # left then right friction-cone edge
        ca, sa = np.cos(sign * alpha), np.sin(sign * alpha)
        f = np.stack([ca * n[:, 0] - sa * n[:, 1], sa * n[:, 0] + ca * n[:, 1]], axis=-1)
        V = np.stack([c2 * f[:, 0], c2 * f[:, 1], x * f[:, 1] - y * f[:, 0]], axis=-1)
        v = np.stack([V[:, 0] - V[:, 2] * y, V[:, 1] + V[:, 2] * x], axis=-1)
        edges.append((V, v))
    (V_l, v_l), (V_r, v_r) = edges

    def cross(a, b):
        return a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]

    inside = (cross(v_r, vp) >= 0) & (cross(vp, v_l) >= 0)
    right = cross(v_r, vp) < 0
    V_b = np.where(right[:, None], V_r, V_l)
    v_b = np.where(right[:, None], v_r, v_l)
    vpn = (vp * n).sum(1)
    vbn = (v_b * n).sum(1)
    slide = V_b * (vpn / np.where(np.abs(vbn) < 1e-15, 1e-15, vbn))[:, None]
    twist = np.where(inside[:, None], stick, slide)
    return np.where((vpn > 0)[:, None], twist, 0.0)


class PushingModel:
    """The hand-relative transition model: object poses (K, 3) in the hand frame.

    Args:
        hand_parts: the hand as convex polygons (hand frame, m).
        shape: the object outline as one convex polygon about its centre of friction.
        params: :class:`PushingParameters`.
        backend: ``"numba"`` (compiled, :mod:`models.planar.kernels`, the default) or
            ``"numpy"`` (this module's array reference; same results, slower).
    """

    def __init__(self, hand_parts: ConvexPolygons, shape: ConvexPolygons,
                 params: PushingParameters = PushingParameters(), backend: str = "numba"):
        if backend not in ("numba", "numpy"):
            raise ValueError(f"backend must be 'numba' or 'numpy', got {backend!r}")
        self.parts = hand_parts
        self.shape = shape
        self.params = params
        self.backend = backend

    def substeps(self, action: np.ndarray) -> int:
        """Physics steps for a hand motion ``action`` = (dx m, dy m, dtheta rad) in the hand
        frame; rotation counts with the hand's 0.1 m reach."""
        a = np.asarray(action, dtype=float)
        travel = max(np.hypot(a[0], a[1]), abs(a[2]) * 0.1)
        return max(1, int(np.ceil(travel / self.params.step_m - 1e-9)))

    def uniforms_per_step(self, action: np.ndarray) -> int:
        """Width D of the uniforms array :meth:`step` consumes for ``action``."""
        return 2 * self.substeps(action)

    def step(self, states: np.ndarray, action: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Advance object poses while the hand makes the motion ``action``.

        Args:
            states: (K, 3) object poses (x m, y m, theta rad) in the hand frame.
            action: (3,) hand motion (dx m, dy m, dtheta rad) in the hand frame.
            u: (K, D) uniforms in [0, 1), D = :meth:`uniforms_per_step` (mu, c per step).

        Returns:
            (K, 3) object poses in the hand frame after the motion.
        """
        states = np.array(states, dtype=float, ndmin=2)
        n = self.substeps(action)
        if u.shape != (len(states), 2 * n):
            raise ValueError(f"u must have shape {(len(states), 2 * n)}, got {u.shape}")
        delta = np.asarray(action, dtype=float) / n
        p = self.params
        if self.backend == "numba":
            from models.planar import kernels

            mu = truncated_normal(u[:, 0::2], p.mu_mean, p.mu_std)
            c = truncated_normal(u[:, 1::2], p.c_mean_m, p.c_std_m)
            return kernels.push(states, delta, n, mu, c, p.contact_iterations,
                                *self.parts.kernel_arrays, *self.shape.object_arrays)
        undo = inverse(delta)
        for i in range(n):
            states = compose(undo, states)  # the hand moves; the object stays in the world
            mu = truncated_normal(u[:, 2 * i], p.mu_mean, p.mu_std)
            c = truncated_normal(u[:, 2 * i + 1], p.c_mean_m, p.c_std_m)
            states = self._resolve(states, delta, mu, c)
        return states

    def _resolve(self, states, delta, mu, c):
        active = np.arange(len(states))
        for _ in range(self.params.contact_iterations):
            pen = deepest_penetration(self.parts, self.shape, states[active])
            hit = pen.depth > OVERLAP_TOLERANCE_M
            if not np.any(hit):
                break
            active = active[hit]
            states[active] = self._push_out(states[active], pen.depth[hit], pen.normal[hit],
                                            pen.point[hit], delta, mu[active], c[active])
        return states

    @staticmethod
    def _push_out(states, depth, normal, point, delta, mu, c):
        """Move overlapping objects out by ``depth`` along the contact normal (hand frame)."""
        cos, sin = np.cos(states[:, 2]), np.sin(states[:, 2])

        def to_object(v):  # rotate hand-frame vectors into the object frame
            return np.stack([cos * v[:, 0] + sin * v[:, 1], -sin * v[:, 0] + cos * v[:, 1]], -1)

        r = to_object(point - states[:, :2])
        n = to_object(normal)
        v_hand = np.stack([delta[0] - delta[2] * point[:, 1],
                           delta[1] + delta[2] * point[:, 0]], axis=-1)
        twist = lynch_twist(r, n, to_object(v_hand), mu, c)
        v_contact = np.stack([twist[:, 0] - twist[:, 2] * r[:, 1],
                              twist[:, 1] + twist[:, 2] * r[:, 0]], axis=-1)
        vcn = (v_contact * n).sum(1)
        pushed = vcn > 1e-12
        scale = np.where(pushed, depth / np.where(pushed, vcn, 1.0), 0.0)
        # Tangent or separating push on an overlapping object: translate it out.
        fallback = np.concatenate([n * depth[:, None], np.zeros((len(n), 1))], axis=1)
        twist = np.where(pushed[:, None], twist * scale[:, None], fallback)
        return compose(states, exp_twist(twist))
