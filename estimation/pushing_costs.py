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
- **Vision** (eq. 4): ``x_t - w_t`` in the world frame, angle wrapped.
- **Stationary prior** (eq. 4): ``x_t - x_{t-1}``, angle wrapped.
"""

from __future__ import annotations

import numpy as np

from models.pose import wrap_angle


def _rotation(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _world_jacobian(theta: float) -> np.ndarray:
    """(3, 3) d(x, y, theta) / d xi: the world-frame change of a local perturbation."""
    J = np.eye(3)
    J[:2, :2] = _rotation(theta)
    return J


def closest_boundary_point(polygon: np.ndarray, q: np.ndarray):
    """The outline's closest point to ``q`` and the signed distance, with derivatives.

    Args:
        polygon: (V, 2) convex, counter-clockwise outline (m).
        q: (2,) a point in the polygon's frame (m).

    Returns:
        (A (2,), dA/dq (2, 2), signed distance (negative inside), d sd / dq (2,)).
        On an edge's interior dA/dq projects onto the edge; at a vertex it is zero.
    """
    a = polygon
    e = np.roll(polygon, -1, axis=0) - a
    length2 = np.einsum("ij,ij->i", e, e)
    t = np.clip(np.einsum("ij,ij->i", q - a, e) / length2, 0.0, 1.0)
    candidates = a + t[:, None] * e
    gaps = q - candidates
    d2 = np.einsum("ij,ij->i", gaps, gaps)
    k = int(np.argmin(d2))
    A = candidates[k]
    unit = e[k] / np.sqrt(length2[k])
    on_edge = 0.0 < t[k] < 1.0
    dA = np.outer(unit, unit) if on_edge else np.zeros((2, 2))
    cross = e[:, 0] * (q[1] - a[:, 1]) - e[:, 1] * (q[0] - a[:, 0])
    inside = bool(np.all(cross > 0))
    distance = float(np.sqrt(d2[k]))
    outward = np.array([unit[1], -unit[0]])
    direction = gaps[k] / distance if distance > 1e-12 else outward
    if inside:
        return A, dA, -distance, -direction
    return A, dA, distance, direction


def _local_point_jacobian(q: np.ndarray) -> np.ndarray:
    """(2, 3) d q / d xi for ``q = R(theta)^T (point - p)``, a fixed world point seen
    from the pose."""
    return np.array([[-1.0, 0.0, q[1]], [0.0, -1.0, -q[0]]])


def contact_point(rod: np.ndarray, force: np.ndarray, radius: float) -> np.ndarray:
    """(2,) the sensed contact point: the rod centre moved by its radius along the force
    it applies to the object (seed 003 sec. IV-C; force and contact normal taken as one)."""
    return rod + radius * force / np.linalg.norm(force)


def contact_residual(pose: np.ndarray, rod: np.ndarray, force: np.ndarray, radius: float,
                     polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 003 eq. 3 for one rod in contact.

    Args:
        pose: (3,) object pose. rod: (2,) rod centre (m, world). force: (2,) the rod's
        force on the object (N, world). radius: rod radius (m). polygon: (V, 2) outline.

    Returns:
        (residual (3,) m, Jacobian (3, 3) with respect to the local perturbation).
    """
    R = _rotation(pose[2])
    p = pose[:2]
    q_rod = R.T @ (rod - p)
    _, _, sd, dsd = closest_boundary_point(polygon, q_rod)
    q_b = R.T @ (contact_point(rod, force, radius) - p)
    A, dA, _, _ = closest_boundary_point(polygon, q_b)
    residual = np.array([sd - radius, *(q_b - A)])
    J = np.empty((3, 3))
    J[0] = dsd @ _local_point_jacobian(q_rod)
    J[1:] = (np.eye(2) - dA) @ _local_point_jacobian(q_b)
    return residual, J


def motion_terms(rods: np.ndarray, forces: np.ndarray, radius: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The pushing inputs of the motion cost from the rods in contact.

    Args:
        rods: (K, 2) centres (m). forces: (K, 2) forces on the object (N). radius: m.

    Returns:
        (total force (2,) N, contact points (K, 2) m).
    """
    points = rods + radius * forces / np.linalg.norm(forces, axis=1, keepdims=True)
    return forces.sum(axis=0), points


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
        (residual (2,) N m^2 / s-like units, d/d xi_previous (2, 3), d/d xi_current (2, 3)).
    """
    p1, p2 = previous[:2], current[:2]
    R1, R2 = _rotation(previous[2]), _rotation(current[2])
    F = forces.sum(axis=0)
    arms = points - p1
    m = float(np.sum(arms[:, 0] * forces[:, 1] - arms[:, 1] * forces[:, 0]))
    dp = p2 - p1
    w = float(wrap_angle(current[2] - previous[2]))
    c2 = c * c
    u = dp * m - c2 * F * w
    r = R1.T @ u
    du_dp1 = -m * np.eye(2) + np.outer(dp, [-F[1], F[0]])
    J1 = np.empty((2, 3))
    J1[:, :2] = R1.T @ du_dp1 @ R1
    J1[:, 2] = R1.T @ (c2 * F) + np.array([r[1], -r[0]])  # d(R1^T)/dtheta u = -J r
    J2 = np.empty((2, 3))
    J2[:, :2] = m * (R1.T @ R2)
    J2[:, 2] = -(R1.T @ (c2 * F))
    return r, J1, J2


def vision_residual(pose: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 003 eq. 4: (3,) world-frame ``pose - measured`` (angle wrapped) and its (3, 3)
    Jacobian."""
    r = pose - measured
    r[2] = float(wrap_angle(r[2]))
    return r, _world_jacobian(pose[2])


def stationary_residual(previous: np.ndarray, current: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed 003 eq. 4: (3,) world-frame ``current - previous`` and its Jacobians (3, 3)
    with respect to ``previous`` and ``current``."""
    r = current - previous
    r[2] = float(wrap_angle(r[2]))
    return r, -_world_jacobian(previous[2]), _world_jacobian(current[2])


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
