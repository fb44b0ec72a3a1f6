"""Gaussian kernel density estimates over planar poses, with Silverman's bandwidth.

The MPF weights each dual particle by the density of the predicted belief at it (thesis
sec. 4.2.3: "Gaussian kernel [...] bandwidth matrix using a multivariate generalization of
Silverman's rule of thumb"). The bandwidth is diagonal: per dimension
``h_j = sigma_j * (4 / ((d + 2) n)) ** (1 / (d + 4))`` with weighted standard deviations
and ``n`` the effective sample size. Orientation lives on the circle: its spread is the
circular standard deviation and kernel differences are wrapped, so particles at +179 deg
and -179 deg are neighbours.

scipy.stats.gaussian_kde is not used because it has no notion of a circular dimension
and builds a full covariance from the data (which collapses when all particles share one
orientation). The sum over kernels is compiled with Numba: Q x N kernel terms with a
running log-sum-exp, no (Q, N) temporaries (the MPF evaluates 25 x 10,000 of them).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

MIN_BANDWIDTH = np.array([1e-4, 1e-4, 1e-3])
"""Floor on each bandwidth (m, m, rad), so identical particles still give a density."""


def silverman_bandwidth(states: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(3,) diagonal bandwidths (m, m, rad) for weighted planar poses (N, 3)."""
    w = weights / weights.sum()
    n_eff = 1.0 / np.sum(w * w)
    d = states.shape[1]
    mean_xy = w @ states[:, :2]
    std_xy = np.sqrt(w @ (states[:, :2] - mean_xy) ** 2)
    resultant = np.hypot(w @ np.cos(states[:, 2]), w @ np.sin(states[:, 2]))
    std_theta = np.sqrt(-2.0 * np.log(np.clip(resultant, 1e-12, 1.0)))
    sigma = np.array([std_xy[0], std_xy[1], std_theta])
    factor = (4.0 / ((d + 2) * n_eff)) ** (1.0 / (d + 4))
    return np.maximum(sigma * factor, MIN_BANDWIDTH)


def log_density(queries: np.ndarray, states: np.ndarray, weights: np.ndarray,
                bandwidth: np.ndarray | None = None) -> np.ndarray:
    """log of sum_i w_i N(q - s_i; 0, diag(h)^2) at each query.

    Args:
        queries: (Q, 3) poses; states: (N, 3) kernel centres; weights: (N,) non-negative.
        bandwidth: (3,) or Silverman's rule when None.

    Returns:
        (Q,) log densities (per m^2 rad).
    """
    w = weights / weights.sum()
    h = silverman_bandwidth(states, w) if bandwidth is None else np.asarray(bandwidth, float)
    norm = -np.log(h).sum() - 1.5 * np.log(2 * np.pi)
    log_w = np.log(np.maximum(w, 1e-300))
    queries = np.ascontiguousarray(queries, dtype=float)
    states = np.ascontiguousarray(states, dtype=float)
    kernel = _sums_parallel if len(states) >= PARALLEL_MIN_CENTRES else _sums_serial
    return kernel(queries, states, log_w, h) + norm


PARALLEL_MIN_CENTRES = 4096
"""Kernel sums over at least this many centres run on all cores."""

NEGLIGIBLE_LOG_TERM = 40.0
"""Terms more than this below a query's largest (a factor e^-40) are left out of its sum."""


def _log_kernel_sums(queries, states, log_w, h):
    """Per query, log sum_i exp(log_w_i - |(q - s_i) / h|^2 / 2), angle wrapped."""
    two_pi = 2.0 * np.pi
    out = np.empty(queries.shape[0])
    terms = np.empty((queries.shape[0], states.shape[0]))
    for q in prange(queries.shape[0]):
        top = -np.inf
        for i in range(states.shape[0]):
            dx = (queries[q, 0] - states[i, 0]) / h[0]
            dy = (queries[q, 1] - states[i, 1]) / h[1]
            a = queries[q, 2] - states[i, 2]
            a = a - two_pi * np.floor((a + np.pi) / two_pi)
            dt = a / h[2]
            terms[q, i] = log_w[i] - 0.5 * (dx * dx + dy * dy + dt * dt)
            top = max(top, terms[q, i])
        total = 0.0
        for i in range(states.shape[0]):
            if terms[q, i] > top - NEGLIGIBLE_LOG_TERM:
                total += np.exp(terms[q, i] - top)
        out[q] = top + np.log(total)
    return out


# Numba's cache keys by function name, not by ``parallel``: only the serial build is cached.
_sums_serial = njit(cache=True)(_log_kernel_sums)
_sums_parallel = njit(parallel=True)(_log_kernel_sums)
