"""Gaussian kernel density estimates over particle states, with Silverman's bandwidth.

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

MIN_LINEAR_BANDWIDTH = 1e-4
"""Floor on a linear column's bandwidth (m), so identical particles still give a density."""

MIN_ANGULAR_BANDWIDTH = 1e-3
"""Floor on an angular column's bandwidth (rad)."""


def _angular_mask(d: int, angular: tuple[int, ...]) -> np.ndarray:
    mask = np.zeros(d, dtype=bool)
    mask[list(angular)] = True
    return mask


def silverman_bandwidth(states: np.ndarray, weights: np.ndarray,
                        angular: tuple[int, ...] = (2,)) -> np.ndarray:
    """(d,) diagonal bandwidths for weighted states (N, d): per column its weighted
    standard deviation (circular for the ``angular`` columns) times
    ``(4 / ((d + 2) n_eff)) ** (1 / (d + 4))``; default: planar poses (m, m, rad)."""
    w = weights / weights.sum()
    n_eff = 1.0 / np.sum(w * w)
    d = states.shape[1]
    mask = _angular_mask(d, angular)
    mean = w @ states
    sigma = np.sqrt(w @ (states - mean) ** 2)
    resultant = np.hypot(w @ np.cos(states[:, mask]), w @ np.sin(states[:, mask]))
    sigma[mask] = np.sqrt(-2.0 * np.log(np.clip(resultant, 1e-12, 1.0)))
    factor = (4.0 / ((d + 2) * n_eff)) ** (1.0 / (d + 4))
    floor = np.where(mask, MIN_ANGULAR_BANDWIDTH, MIN_LINEAR_BANDWIDTH)
    return np.maximum(sigma * factor, floor)


def log_density(queries: np.ndarray, states: np.ndarray, weights: np.ndarray,
                bandwidth: np.ndarray | None = None, angular: tuple[int, ...] = (2,)
                ) -> np.ndarray:
    """log of sum_i w_i N(q - s_i; 0, diag(h)^2) at each query.

    Args:
        queries: (Q, d) states; states: (N, d) kernel centres; weights: (N,) non-negative.
        bandwidth: (d,) or Silverman's rule when None.
        angular: the columns whose differences are wrapped (default: a planar pose's
            orientation).

    Returns:
        (Q,) log densities (per unit volume of the state space, e.g. per m^2 rad).
    """
    w = weights / weights.sum()
    d = states.shape[1]
    h = (silverman_bandwidth(states, w, angular) if bandwidth is None
         else np.asarray(bandwidth, float))
    norm = -np.log(h).sum() - 0.5 * d * np.log(2 * np.pi)
    log_w = np.log(np.maximum(w, 1e-300))
    queries = np.ascontiguousarray(queries, dtype=float)
    states = np.ascontiguousarray(states, dtype=float)
    kernel = _sums_parallel if len(states) >= PARALLEL_MIN_CENTRES else _sums_serial
    return kernel(queries, states, log_w, h, _angular_mask(d, angular)) + norm


def leave_one_out_log_density(indices: np.ndarray, states: np.ndarray, weights: np.ndarray,
                              bandwidth: np.ndarray | None = None,
                              angular: tuple[int, ...] = (2,)) -> np.ndarray:
    """(Q,) log density of the weighted states (N, d) at ``states[indices]``, each point's
    own kernel left out (the leave-one-out estimate: a point's own kernel would dominate
    its density where particles are sparse, as in a 7-D configuration space). -inf where
    nothing but the point itself contributes."""
    w = weights / weights.sum()
    d = states.shape[1]
    h = (silverman_bandwidth(states, w, angular) if bandwidth is None
         else np.asarray(bandwidth, float))
    norm = -np.log(h).sum() - 0.5 * d * np.log(2 * np.pi)
    with_self = log_density(states[indices], states, w, h, angular)
    own = np.log(np.maximum(w[indices], 1e-300)) + norm
    excess = with_self - own  # log (1 + others / own) >= 0
    with np.errstate(divide="ignore"):
        return own + np.log(np.maximum(np.expm1(np.maximum(excess, 0.0)), 0.0))


PARALLEL_MIN_CENTRES = 4096
"""Kernel sums over at least this many centres run on all cores."""

NEGLIGIBLE_LOG_TERM = 40.0
"""Terms more than this below a query's largest (a factor e^-40) are left out of its sum."""


def _log_kernel_sums(queries, states, log_w, h, angular):
    """Per query, log sum_i exp(log_w_i - |(q - s_i) / h|^2 / 2), angular columns wrapped."""
    two_pi = 2.0 * np.pi
    out = np.empty(queries.shape[0])
    terms = np.empty((queries.shape[0], states.shape[0]))
    for q in prange(queries.shape[0]):
        top = -np.inf
        for i in range(states.shape[0]):
            total = 0.0
            for j in range(states.shape[1]):
                a = queries[q, j] - states[i, j]
                if angular[j]:
                    a = a - two_pi * np.floor((a + np.pi) / two_pi)
                a = a / h[j]
                total += a * a
            terms[q, i] = log_w[i] - 0.5 * total
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
