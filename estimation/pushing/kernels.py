"""Compiled inner loops of the contact cost (:mod:`estimation.pushing.costs`).

The contact cost is linearised hundreds of times per batch relinearisation, each time
from a GTSAM callback; in numpy its many small array operations cost about 60 us a call,
compiled about 2 us. The functions here are the scalar arithmetic only; their meaning and
tests live with :func:`estimation.pushing.costs.contact_residual`.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def closest_point(vertices, edges, length2, qx, qy):
    """Closest outline point to (qx, qy) and the signed distance, with derivatives.

    Returns:
        (ax, ay, on_edge, ux, uy, sd, gx, gy): the point; whether it lies inside an edge
        (then dA/dq = u u^T, else 0) and that edge's unit direction; the signed distance
        (negative inside) and its gradient.
    """
    best = np.inf
    k_best = 0
    t_best = 0.0
    gap_x = 0.0
    gap_y = 0.0
    inside = True
    for k in range(vertices.shape[0]):
        rx = qx - vertices[k, 0]
        ry = qy - vertices[k, 1]
        ex = edges[k, 0]
        ey = edges[k, 1]
        if ex * ry - ey * rx <= 0.0:
            inside = False
        t = (rx * ex + ry * ey) / length2[k]
        t = min(1.0, max(0.0, t))
        gx = rx - t * ex
        gy = ry - t * ey
        d2 = gx * gx + gy * gy
        if d2 < best:
            best, k_best, t_best, gap_x, gap_y = d2, k, t, gx, gy
    scale = math.sqrt(length2[k_best])
    ux = edges[k_best, 0] / scale
    uy = edges[k_best, 1] / scale
    distance = math.sqrt(best)
    if distance > 1e-12:
        dx, dy = gap_x / distance, gap_y / distance
    else:
        dx, dy = uy, -ux
    sign = -1.0 if inside else 1.0
    return (qx - gap_x, qy - gap_y, 0.0 < t_best < 1.0, ux, uy, sign * distance,
            sign * dx, sign * dy)


@numba.njit(cache=True)
def contact(pose, rod, force, radius, vertices, edges, length2):
    """Residual (3,) and Jacobian (3, 3) of seed 003's contact cost (see
    :func:`estimation.pushing.costs.contact_residual`)."""
    c = math.cos(pose[2])
    s = math.sin(pose[2])
    # the rod centre in the object frame
    wx = rod[0] - pose[0]
    wy = rod[1] - pose[1]
    qx = c * wx + s * wy
    qy = -s * wx + c * wy
    sd_out = closest_point(vertices, edges, length2, qx, qy)
    sd, gx, gy = sd_out[5], sd_out[6], sd_out[7]
    # the sensed contact point in the object frame
    norm = math.sqrt(force[0] * force[0] + force[1] * force[1])
    bx = wx + radius * force[0] / norm
    by = wy + radius * force[1] / norm
    px = c * bx + s * by
    py = -s * bx + c * by
    ax, ay, on_edge, ux, uy = closest_point(vertices, edges, length2, px, py)[:5]
    r = np.empty(3)
    J = np.empty((3, 3))
    r[0] = sd - radius
    r[1] = px - ax
    r[2] = py - ay
    # dq/dxi = [[-1, 0, qy], [0, -1, -qx]]
    J[0, 0] = -gx
    J[0, 1] = -gy
    J[0, 2] = gx * qy - gy * qx
    # (I - dA/dq) dq/dxi for the contact point
    if on_edge:
        m00, m01, m11 = 1.0 - ux * ux, -ux * uy, 1.0 - uy * uy
    else:
        m00, m01, m11 = 1.0, 0.0, 1.0
    J[1, 0] = -m00
    J[1, 1] = -m01
    J[1, 2] = m00 * py - m01 * px
    J[2, 0] = -m01
    J[2, 1] = -m11
    J[2, 2] = m01 * py - m11 * px
    return r, J


@numba.njit(cache=True)
def motion(previous, current, forces, points, c):
    """Residual (2,) and Jacobians (2, 3), (2, 3) of seed 003's motion cost (see
    :func:`estimation.pushing.costs.motion_residual`)."""
    c1 = math.cos(previous[2])
    s1 = math.sin(previous[2])
    c2 = math.cos(current[2])
    s2 = math.sin(current[2])
    Fx = 0.0
    Fy = 0.0
    m = 0.0
    for i in range(forces.shape[0]):
        Fx += forces[i, 0]
        Fy += forces[i, 1]
        m += ((points[i, 0] - previous[0]) * forces[i, 1]
              - (points[i, 1] - previous[1]) * forces[i, 0])
    dx = current[0] - previous[0]
    dy = current[1] - previous[1]
    w = (current[2] - previous[2] + math.pi) % (2.0 * math.pi) - math.pi
    c2F_x = c * c * Fx
    c2F_y = c * c * Fy
    ux = dx * m - c2F_x * w
    uy = dy * m - c2F_y * w
    r = np.empty(2)
    r[0] = c1 * ux + s1 * uy  # R1^T u
    r[1] = -s1 * ux + c1 * uy
    # du/dp1 = -m I + dp [-Fy, Fx]
    d00 = -m - dx * Fy
    d01 = dx * Fx
    d10 = -dy * Fy
    d11 = -m + dy * Fx
    # R1^T (du/dp1) R1
    a00 = c1 * d00 + s1 * d10
    a01 = c1 * d01 + s1 * d11
    a10 = -s1 * d00 + c1 * d10
    a11 = -s1 * d01 + c1 * d11
    J1 = np.empty((2, 3))
    J1[0, 0] = a00 * c1 + a01 * s1
    J1[0, 1] = -a00 * s1 + a01 * c1
    J1[1, 0] = a10 * c1 + a11 * s1
    J1[1, 1] = -a10 * s1 + a11 * c1
    g0 = c1 * c2F_x + s1 * c2F_y  # R1^T c^2 F
    g1 = -s1 * c2F_x + c1 * c2F_y
    J1[0, 2] = g0 + r[1]
    J1[1, 2] = g1 - r[0]
    # m R1^T R2 = m R(theta2 - theta1)
    cd = c1 * c2 + s1 * s2
    sd = c1 * s2 - s1 * c2
    J2 = np.empty((2, 3))
    J2[0, 0] = m * cd
    J2[0, 1] = -m * sd
    J2[1, 0] = m * sd
    J2[1, 1] = m * cd
    J2[0, 2] = -g0
    J2[1, 2] = -g1
    return r, J1, J2
