"""The four costs of seed 003 (Yu and Rodriguez, ICRA 2018, sec. IV) as residuals with
analytic Jacobians, shared by the factor-graph smoother and the EKF.

Poses are ``(x, y, theta)`` in the world (m, rad). Every Jacobian is with respect to the
pose's *local* perturbation ``xi = (dx, dy, dtheta)`` in the body frame, the convention of
GTSAM's ``Pose2`` (``p <- p + R(theta) (dx, dy)``, ``theta <- theta + dtheta`` to first
order), so they plug into ``gtsam.CustomFactor`` unchanged.

- **Motion** (eq. 2, in the multiplied form of the published code, which avoids dividing
  by the angular velocity or the moment): with the rods' contact points ``c_i`` and forces
  ``f_i`` at ``t-1`` (world), ``F = sum f_i``, ``m = sum (c_i - p_{t-1}) x f_i`` (the moment
  about the object's centre; a cross product does not depend on the frame),
  ``dp = p_t - p_{t-1}``, ``w = wrap(theta_t - theta_{t-1})``:
  ``M = R(theta_{t-1})^T (dp m - c^2 F w)``, which is ``[vx m - c^2 Fx w, vy m - c^2 Fy w]``
  in the object frame of ``x_{t-1}``.
- **Contact** (eq. 3, per rod in contact): ``[sd(q_rod) - r, q_B - A(q_B)]``: the rod
  centre's signed distance to the outline minus the rod radius, and the sensed contact
  point ``B = rod + r f / |f|`` (the rod centre moved along the force it applies to the
  object) minus its closest point ``A`` on the outline, both in the object frame.
- **Penetration** (not in seed 003): for a rod whose position is known but whose force
  reading is not (a dropped force sample), ``max(0, r - sd(q_rod))``: the rod may or may
  not touch, but it cannot be inside the object, so while blind the object is pushed
  along by the rods rather than left behind.
- **Vision** (eq. 4): ``x_t - w_t`` in the world frame, angle wrapped.
- **Stationary prior** (eq. 4): ``x_t - x_{t-1}``, angle wrapped.
"""

from __future__ import annotations

import math

import numpy as np

from estimation.pushing import kernels


class Outline:
    """A convex outline with its edges precomputed (the contact cost queries it at every
    linearisation).

    Args:
        polygon: (V, 2) convex, counter-clockwise vertices (m).
    """

    def __init__(self, polygon: np.ndarray):
        self.vertices = np.ascontiguousarray(polygon, dtype=float)
        self.edges = np.roll(self.vertices, -1, axis=0) - self.vertices
        self.length2 = np.einsum("ij,ij->i", self.edges, self.edges)


def closest_boundary_point(outline: Outline | np.ndarray, q: np.ndarray):
    """The outline's closest point to ``q`` and the signed distance, with derivatives.

    Args:
        outline: an :class:`Outline` (or its (V, 2) convex, counter-clockwise polygon).
        q: (2,) a point in the outline's frame (m).

    Returns:
        (A (2,), dA/dq (2, 2), signed distance (negative inside), d sd / dq (2,)).
        On an edge's interior dA/dq projects onto the edge; at a vertex it is zero.
    """
    if not isinstance(outline, Outline):
        outline = Outline(outline)
    ax, ay, on_edge, ux, uy, sd, gx, gy = kernels.closest_point(
        outline.vertices, outline.edges, outline.length2, float(q[0]), float(q[1]))
    dA = np.outer([ux, uy], [ux, uy]) if on_edge else np.zeros((2, 2))
    return np.array([ax, ay]), dA, sd, np.array([gx, gy])


def contact_residual(pose: np.ndarray, rod: np.ndarray, force: np.ndarray, radius: float,
                     polygon: Outline | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 003 eq. 3 for one rod in contact.

    With ``q = R(theta)^T (point - p)`` a world point seen from the pose, ``dq/dxi =
    [[-1, 0, q_y], [0, -1, -q_x]]``; the residual's rows are ``grad sd(q_rod) dq_rod/dxi``
    and ``(I - dA/dq) dq_B/dxi``. Compiled (:mod:`estimation.pushing.kernels`).

    Args:
        pose: (3,) object pose. rod: (2,) rod centre (m, world). force: (2,) the rod's
        force on the object (N, world). radius: rod radius (m). polygon: the outline (an
        :class:`Outline` or its (V, 2) vertices).

    Returns:
        (residual (3,) m, Jacobian (3, 3) with respect to the local perturbation).
    """
    if not isinstance(polygon, Outline):
        polygon = Outline(polygon)
    return kernels.contact(np.asarray(pose, dtype=float), np.asarray(rod, dtype=float),
                           np.asarray(force, dtype=float), float(radius), polygon.vertices,
                           polygon.edges, polygon.length2)


def penetration_residual(pose: np.ndarray, rod: np.ndarray, radius: float,
                         polygon: Outline | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How deep a rod of unknown force sits inside the object (see the module docstring).

    Args:
        pose: (3,) object pose. rod: (2,) rod centre (m, world). radius: rod radius (m).
        polygon: the outline (an :class:`Outline` or its (V, 2) vertices).

    Returns:
        (residual (1,) m: ``max(0, r - sd(q_rod))``, Jacobian (1, 3) with respect to the
        local perturbation: ``-grad sd(q_rod) dq_rod/dxi`` while the rod penetrates, else
        zero).
    """
    x, y, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    dx, dy = rod[0] - x, rod[1] - y
    q = np.array([c * dx + s * dy, -s * dx + c * dy])
    _, _, sd, grad = closest_boundary_point(polygon, q)
    depth = radius - sd
    if depth <= 0.0:
        return np.zeros(1), np.zeros((1, 3))
    dq = np.array([[-1.0, 0.0, q[1]], [0.0, -1.0, -q[0]]])
    return np.array([depth]), -(grad @ dq)[None]


def contact_points(rods: np.ndarray, forces: np.ndarray, radius: float) -> np.ndarray:
    """(K, 2) the sensed contact points (m, world) of rods (K, 2) in contact, each the rod
    centre moved by ``radius`` along the force (K, 2) it applies to the object (seed 003
    sec. IV-C: the force and the contact normal taken as one)."""
    return rods + radius * forces / np.linalg.norm(forces, axis=1, keepdims=True)


def motion_residual(previous: np.ndarray, current: np.ndarray, forces: np.ndarray,
                    points: np.ndarray, c: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed 003 eq. 2 in multiplied form (see the module docstring).

    Args:
        previous, current: (3,) poses at t-1 and t.
        forces: (K, 2) forces on the object at t-1 (N, world), rods in contact only.
        points: (K, 2) their contact points (m, world).
        c: the limit surface's ratio m_max / f_max (m).

    Returns:
        (residual (2,) in N m^2, d/d xi_previous (2, 3), d/d xi_current (2, 3)). With
        ``u = dp m - c^2 F w``: ``du/dp_prev = -m I + dp [-F_y, F_x]``, ``du/dp = m I``,
        ``du/dtheta_prev = c^2 F = -du/dtheta``, and ``d(R^T)/dtheta u = -[[0, -1], [1, 0]] r``.
        Compiled (:mod:`estimation.pushing.kernels`).
    """
    return kernels.motion(np.asarray(previous, dtype=float), np.asarray(current, dtype=float),
                          np.ascontiguousarray(forces, dtype=float),
                          np.ascontiguousarray(points, dtype=float), float(c))


def _wrap(angle: float) -> float:
    """Scalar :func:`models.pose.wrap_angle` (the costs run inside solver callbacks, where
    numpy's per-call overhead would dominate)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def vision_residual(pose: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 003 eq. 4: (3,) world-frame ``pose - measured`` (angle wrapped) and its (3, 3)
    Jacobian."""
    x, y, theta = pose
    c, s = math.cos(theta), math.sin(theta)
    r = np.array([x - measured[0], y - measured[1], _wrap(theta - measured[2])])
    return r, np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def stationary_residual(previous: np.ndarray, current: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed 003 eq. 4: (3,) world-frame ``current - previous`` and its Jacobians (3, 3)
    with respect to ``previous`` and ``current``."""
    c1, s1 = math.cos(previous[2]), math.sin(previous[2])
    c2, s2 = math.cos(current[2]), math.sin(current[2])
    r = np.array([current[0] - previous[0], current[1] - previous[1],
                  _wrap(current[2] - previous[2])])
    return (r, np.array([[-c1, s1, 0.0], [-s1, -c1, 0.0], [0.0, 0.0, -1.0]]),
            np.array([[c2, -s2, 0.0], [s2, c2, 0.0], [0.0, 0.0, 1.0]]))


def limit_surface_c(polygon: np.ndarray, *, samples: int = 20000) -> float:
    """c = m_max / f_max (m) for a uniform pressure over the convex ``polygon``: the mean
    distance of the support area from its centre (reference: a 90 mm square gives about
    0.034 m). Computed by a fixed quadrature grid (deterministic)."""
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    n = int(np.sqrt(samples))
    xs = np.linspace(lo[0], hi[0], n)
    ys = np.linspace(lo[1], hi[1], n)
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    e = np.roll(polygon, -1, axis=0) - polygon
    cross = (e[None, :, 0] * (grid[:, None, 1] - polygon[None, :, 1])
             - e[None, :, 1] * (grid[:, None, 0] - polygon[None, :, 0]))
    inside = grid[np.all(cross >= 0, axis=1)]
    return float(np.mean(np.linalg.norm(inside, axis=1)))
