"""Compiled (Numba) kernels for the planar world's hot paths: the pushing model's 1 mm
steps, hand-object signed distances, and the observation model's contact readings.

Why Numba: a step resolves contacts one after another (a Gauss-Seidel sweep), so the work
per particle is a short, branchy loop. In numpy every sweep is a dozen array passes over
all (particle, part) pairs, most of which are far apart; compiled, each particle stops as
soon as it is resolved and skips far parts after one distance check. Small batches run
on one thread (the MPF's 100 particles: a thread pool's start-up would cost more than the
work; the studies run one process per core anyway), large ones on all cores. The
formulas are the ones of :mod:`models.planar.polygon` and :mod:`models.planar.pushing`,
which remain the readable reference (``PlanarWorld.load(..., backend="numpy")``);
``tests/models/planar/test_kernels.py`` checks both agree and ``cmanip bench mpf`` times
both in the same run.

Kernels take polygon data as plain arrays (see :class:`~models.planar.polygon.
ConvexPolygons`): ``verts (P, V, 2)``, ``normals (P, V, 2)``, ``support (P, V)``,
``count (P,)`` real vertices, ``centers (P, 2)``, ``radii (P,)``; the object's radius
``orad`` is measured from its body origin (the pose), not from its vertex mean.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from models.planar.tolerances import CONTACT_POINT_TOLERANCE_M as _POINT_TOL
from models.planar.tolerances import OVERLAP_TOLERANCE_M as _OVERLAP_TOL


@njit(cache=True, inline="always", fastmath=True)
def _posed(x, y, c, s, ov, on, osup, B, nB, hB):
    """Object vertices, normals and supports at pose (x, y, cos, sin) into B, nB, hB."""
    for j in range(ov.shape[0]):
        B[j, 0] = x + c * ov[j, 0] - s * ov[j, 1]
        B[j, 1] = y + s * ov[j, 0] + c * ov[j, 1]
        nB[j, 0] = c * on[j, 0] - s * on[j, 1]
        nB[j, 1] = s * on[j, 0] + c * on[j, 1]
        hB[j] = osup[j] + nB[j, 0] * x + nB[j, 1] * y


@njit(cache=True, inline="always", fastmath=True)
def _sat(verts, normals, support, count, p, B, nB, hB, cutoff):
    """Largest separating-axis separation of part p and the posed object, and its axis:
    (sep, from_part, axis index). Stops at the first axis whose separation reaches
    ``cutoff``; the separation returned is then only a lower bound (>= cutoff)."""
    best, from_a, axis = -1e300, True, 0
    for i in range(count[p]):
        lo = 1e300
        for j in range(B.shape[0]):
            v = normals[p, i, 0] * B[j, 0] + normals[p, i, 1] * B[j, 1]
            lo = min(lo, v)
        sep = lo - support[p, i]
        if sep > best:
            best, from_a, axis = sep, True, i
            if best >= cutoff:
                return best, from_a, axis
    for i in range(B.shape[0]):
        lo = 1e300
        for j in range(count[p]):
            v = nB[i, 0] * verts[p, j, 0] + nB[i, 1] * verts[p, j, 1]
            lo = min(lo, v)
        sep = lo - hB[i]
        if sep > best:
            best, from_a, axis = sep, False, i
            if best >= cutoff:
                return best, from_a, axis
    return best, from_a, axis


@njit(cache=True, inline="always", fastmath=True)
def _point_edges(px, py, verts, n):
    """Squared distance from a point to the closed polygon boundary ``verts[:n]``."""
    best = 1e300
    for i in range(n):
        ax, ay = verts[i, 0], verts[i, 1]
        bx, by = verts[(i + 1) % n, 0], verts[(i + 1) % n, 1]
        dx, dy = bx - ax, by - ay
        length2 = max(dx * dx + dy * dy, 1e-18)
        t = min(max(((px - ax) * dx + (py - ay) * dy) / length2, 0.0), 1.0)
        gx, gy = px - ax - t * dx, py - ay - t * dy
        best = min(best, gx * gx + gy * gy)
    return best


def _signed_distances(poses, verts, normals, support, count, centers, radii,
                     ov, on, osup, orad, exact_within):
    """(K, P) signed distances; pairs farther than ``exact_within`` get the bounding-circle
    lower bound (as :func:`models.planar.polygon.signed_distances`)."""
    K, P, V = poses.shape[0], verts.shape[0], ov.shape[0]
    out = np.empty((K, P))
    B_all, nB_all, hB_all = np.empty((K, V, 2)), np.empty((K, V, 2)), np.empty((K, V))
    for k in prange(K):
        c, s = np.cos(poses[k, 2]), np.sin(poses[k, 2])
        B, nB, hB = B_all[k], nB_all[k], hB_all[k]
        _posed(poses[k, 0], poses[k, 1], c, s, ov, on, osup, B, nB, hB)
        for p in range(P):
            gap = np.hypot(poses[k, 0] - centers[p, 0], poses[k, 1] - centers[p, 1])
            bound = gap - radii[p] - orad
            if bound > exact_within:
                out[k, p] = bound
                continue
            sep, _, _ = _sat(verts, normals, support, count, p, B, nB, hB, exact_within)
            if sep <= 0 or sep >= exact_within:  # overlap depth, or a far pair's lower bound
                out[k, p] = sep
                continue
            d = 1e300
            for j in range(V):
                d = min(d, _point_edges(B[j, 0], B[j, 1], verts[p], count[p]))
            for j in range(count[p]):
                d = min(d, _point_edges(verts[p, j, 0], verts[p, j, 1], B, V))
            out[k, p] = np.sqrt(d)
    return out


@njit(cache=True, inline="always", fastmath=True)
def _within(verts, normals, support, count, centers, radii, p, x, y, orad, B, nB, hB, tol):
    """Whether part p and the posed object (centre x, y) are within ``tol`` of each other."""
    if np.hypot(x - centers[p, 0], y - centers[p, 1]) - radii[p] - orad > tol:
        return False
    sep, _, _ = _sat(verts, normals, support, count, p, B, nB, hB, tol)
    if sep <= 0:
        return True
    if sep > tol:
        return False
    tol2 = tol * tol
    for j in range(B.shape[0]):
        if _point_edges(B[j, 0], B[j, 1], verts[p], count[p]) <= tol2:
            return True
    for j in range(count[p]):
        if _point_edges(verts[p, j, 0], verts[p, j, 1], B, B.shape[0]) <= tol2:
            return True
    return False


def _contact_readings(poses, hv, hn, hs, hc, hcen, hrad, sv, sn, ss, sc, scen, srad, owner,
                      sensors, ov, on, osup, orad, tol):
    """Per pose: does the object touch the hand (K,), and which sensors (K, S) it touches,
    within ``tol`` (m). Sensor segments lie on the hand's outline, so a pose that does not
    touch the hand touches no sensor and its sensors are not tested; a sensor's segments
    are tested until the first that touches."""
    K, V = poses.shape[0], ov.shape[0]
    touching = np.zeros((K, sensors), dtype=np.bool_)
    contact = np.zeros(K, dtype=np.bool_)
    B_all, nB_all, hB_all = np.empty((K, V, 2)), np.empty((K, V, 2)), np.empty((K, V))
    for k in prange(K):
        x, y = poses[k, 0], poses[k, 1]
        c, s = np.cos(poses[k, 2]), np.sin(poses[k, 2])
        B, nB, hB = B_all[k], nB_all[k], hB_all[k]
        _posed(x, y, c, s, ov, on, osup, B, nB, hB)
        for p in range(hv.shape[0]):
            if _within(hv, hn, hs, hc, hcen, hrad, p, x, y, orad, B, nB, hB, tol):
                contact[k] = True
                break
        if not contact[k]:
            continue
        for g in range(sv.shape[0]):
            if not touching[k, owner[g]] and _within(sv, sn, ss, sc, scen, srad, g, x, y,
                                                      orad, B, nB, hB, tol):
                touching[k, owner[g]] = True
    return contact, touching


@njit(cache=True, inline="always", fastmath=True)
def _lynch(rx, ry, nx, ny, vx, vy, mu, c):
    """Object twist (object frame) for a point push; see models.planar.pushing."""
    c2 = c * c
    vpn = vx * nx + vy * ny
    if vpn <= 0:
        return 0.0, 0.0, 0.0
    D = c2 + rx * rx + ry * ry
    alpha = np.arctan(mu)
    ca, sa = np.cos(alpha), np.sin(alpha)
    # left (+alpha) and right (-alpha) friction-cone edges and their contact velocities
    flx, fly = ca * nx - sa * ny, sa * nx + ca * ny
    frx, fry = ca * nx + sa * ny, -sa * nx + ca * ny
    Vl0, Vl1, Vl2 = c2 * flx, c2 * fly, rx * fly - ry * flx
    Vr0, Vr1, Vr2 = c2 * frx, c2 * fry, rx * fry - ry * frx
    vlx, vly = Vl0 - Vl2 * ry, Vl1 + Vl2 * rx
    vrx, vry = Vr0 - Vr2 * ry, Vr1 + Vr2 * rx
    cross_r = vrx * vy - vry * vx
    cross_l = vx * vly - vy * vlx
    if cross_r >= 0 and cross_l >= 0:
        return (((c2 + rx * rx) * vx + rx * ry * vy) / D,
                (rx * ry * vx + (c2 + ry * ry) * vy) / D,
                (rx * vy - ry * vx) / D)
    if cross_r < 0:
        V0, V1, V2, vbn = Vr0, Vr1, Vr2, vrx * nx + vry * ny
    else:
        V0, V1, V2, vbn = Vl0, Vl1, Vl2, vlx * nx + vly * ny
    if abs(vbn) < 1e-15:
        vbn = 1e-15
    k = vpn / vbn
    return V0 * k, V1 * k, V2 * k


def _push(states, delta, steps, mu, c, iterations, verts, normals, support, count, centers,
         radii, ov, on, osup, orad):
    """Advance (K, 3) object poses (hand frame) while the hand moves ``delta`` per step.

    Args:
        states: (K, 3) poses, updated copy returned.
        delta: (3,) hand motion per step (hand frame).
        steps: number of steps; mu, c: (K, steps) friction and limit-surface radius.
        iterations: contact resolutions per step.
    """
    K, P, V = states.shape[0], verts.shape[0], ov.shape[0]
    out = states.copy()
    # inverse of delta
    cd, sd = np.cos(delta[2]), np.sin(delta[2])
    ux = -(cd * delta[0] + sd * delta[1])
    uy = -(-sd * delta[0] + cd * delta[1])
    ut = -delta[2]
    cu, su = np.cos(ut), np.sin(ut)
    B_all, nB_all, hB_all = np.empty((K, V, 2)), np.empty((K, V, 2)), np.empty((K, V))
    for k in prange(K):
        B, nB, hB = B_all[k], nB_all[k], hB_all[k]
        x, y, t = out[k, 0], out[k, 1], out[k, 2]
        for step in range(steps):
            x, y, t = ux + cu * x - su * y, uy + su * x + cu * y, t + ut
            for _ in range(iterations):
                ct, st = np.cos(t), np.sin(t)
                _posed(x, y, ct, st, ov, on, osup, B, nB, hB)
                best, best_p, best_a, best_i = 0.0, -1, True, 0
                for p in range(P):
                    gap = np.hypot(x - centers[p, 0], y - centers[p, 1])
                    if gap - radii[p] - orad > 0:
                        continue
                    sep, from_a, axis = _sat(verts, normals, support, count, p, B, nB, hB,
                                             min(best, -_OVERLAP_TOL))
                    if sep < -_OVERLAP_TOL and sep < best:
                        best, best_p, best_a, best_i = sep, p, from_a, axis
                if best_p < 0:
                    break
                p = best_p
                # contact normal (object's way out) and point (mean of deepest vertices)
                px, py, m = 0.0, 0.0, 0
                if best_a:
                    mx, my = normals[p, best_i, 0], normals[p, best_i, 1]
                    lo = 1e300
                    for j in range(V):
                        lo = min(lo, mx * B[j, 0] + my * B[j, 1])
                    for j in range(V):
                        if mx * B[j, 0] + my * B[j, 1] <= lo + _POINT_TOL:
                            px += B[j, 0]
                            py += B[j, 1]
                            m += 1
                else:
                    bx, by = nB[best_i, 0], nB[best_i, 1]
                    mx, my = -bx, -by
                    lo = 1e300
                    for j in range(count[p]):
                        lo = min(lo, bx * verts[p, j, 0] + by * verts[p, j, 1])
                    for j in range(count[p]):
                        if bx * verts[p, j, 0] + by * verts[p, j, 1] <= lo + _POINT_TOL:
                            px += verts[p, j, 0]
                            py += verts[p, j, 1]
                            m += 1
                px, py = px / m, py / m
                depth = -best
                # to the object frame
                rx, ry = ct * (px - x) + st * (py - y), -st * (px - x) + ct * (py - y)
                nx, ny = ct * mx + st * my, -st * mx + ct * my
                hvx, hvy = delta[0] - delta[2] * py, delta[1] + delta[2] * px
                vx, vy = ct * hvx + st * hvy, -st * hvx + ct * hvy
                w0, w1, w2 = _lynch(rx, ry, nx, ny, vx, vy, mu[k, step], c[k, step])
                vcn = (w0 - w2 * ry) * nx + (w1 + w2 * rx) * ny
                if vcn > 1e-12:
                    scale = depth / vcn
                    w0, w1, w2 = w0 * scale, w1 * scale, w2 * scale
                else:
                    w0, w1, w2 = nx * depth, ny * depth, 0.0
                # exp of the body twist, composed onto the pose
                if abs(w2) < 1e-9:
                    sw, cw = 1.0 - w2 * w2 / 6, w2 / 2
                else:
                    sw, cw = np.sin(w2) / w2, (1 - np.cos(w2)) / w2
                dx, dy = sw * w0 - cw * w1, cw * w0 + sw * w1
                x, y, t = x + ct * dx - st * dy, y + st * dx + ct * dy, t + w2
        out[k, 0], out[k, 1] = x, y
        out[k, 2] = (t + np.pi) % (2 * np.pi) - np.pi
    return out


PARALLEL_MIN_POSES = 4096
"""Batches at least this large run on all cores (Numba threads); smaller ones on one, where
starting the thread pool would cost more than the work (the MPF's 100 particles)."""

# Numba's on-disk cache keys a function by its name, not by the ``parallel`` flag: only the
# serial builds are cached; the threaded ones compile on first use in a process.
_push_serial = njit(cache=True, fastmath=True)(_push)
_push_parallel = njit(parallel=True, fastmath=True)(_push)
_distances_serial = njit(cache=True)(_signed_distances)
_distances_parallel = njit(parallel=True)(_signed_distances)
_readings_serial = njit(cache=True)(_contact_readings)
_readings_parallel = njit(parallel=True)(_contact_readings)


def push(states, *args):
    """See :func:`_push`; picks the threaded build for large batches."""
    kernel = _push_parallel if len(states) >= PARALLEL_MIN_POSES else _push_serial
    return kernel(states, *args)


def signed_distances(poses, *args):
    """See :func:`_signed_distances`; picks the threaded build for large batches."""
    kernel = _distances_parallel if len(poses) >= PARALLEL_MIN_POSES else _distances_serial
    return kernel(poses, *args)


def contact_readings(poses, *args):
    """See :func:`_contact_readings`; picks the threaded build for large batches."""
    kernel = _readings_parallel if len(poses) >= PARALLEL_MIN_POSES else _readings_serial
    return kernel(poses, *args)
