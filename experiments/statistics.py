"""Small statistics shared by the studies: intervals and the fault bench's tests."""

from __future__ import annotations

from functools import lru_cache

import numpy as np


def wilson_interval(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % (``z = 1.96``) Wilson score interval of a proportion ``successes / n``."""
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # the interval lies in [0, 1]; at 0 or n successes rounding leaves a -1e-17 or 1 + 1e-16
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


def half_width(values: np.ndarray, z: float = 1.96) -> float:
    """Half-width of the 95 % (``z = 1.96``) normal interval of the mean of ``values``
    (0 for fewer than two values)."""
    values = np.asarray(values, dtype=float)
    return float(z * values.std(ddof=1) / np.sqrt(len(values))) if len(values) > 1 else 0.0


def clustered_half_width(groups: list[np.ndarray], z: float = 1.96) -> float:
    """Half-width of the 95 % (``z = 1.96``) interval of the mean of all the values in
    ``groups``, the groups independent and the values within a group possibly correlated
    (e.g. runs ranked against the same clean draws): the cluster-robust standard error,
    ``sqrt(sum_g (sum of g - n_g mean)^2) / N`` with the usual ``G / (G - 1)`` correction
    (0 for fewer than two groups)."""
    if len(groups) < 2:
        return 0.0
    sums = np.array([np.sum(g) for g in groups], dtype=float)
    sizes = np.array([len(g) for g in groups], dtype=float)
    mean = sums.sum() / sizes.sum()
    variance = np.sum((sums - sizes * mean) ** 2) * len(groups) / (len(groups) - 1)
    return float(z * np.sqrt(variance) / sizes.sum())


def holm(p_values: dict, level: float = 0.05) -> dict:
    """Holm's step-down test over ``p_values`` (key -> p): key -> rejected at ``level``
    with the family-wise error rate held."""
    rejected, still = {}, True
    for i, (key, p) in enumerate(sorted(p_values.items(), key=lambda item: item[1])):
        still = still and p <= level / (len(p_values) - i)
        rejected[key] = still
    return rejected


@lru_cache(maxsize=64)
def mann_whitney_null(m: int, n: int) -> np.ndarray:
    """(m n + 1,) the probability of each Mann-Whitney count U (pairs in which one of ``m``
    runs exceeds one of ``n`` others) when all ``m + n`` are exchangeable, by the
    recursion over the largest of them. Cached (every experiment of a group asks for the
    same ``m, n``) and read-only, so a caller cannot change the cached table."""
    counts = {(0, j): np.ones(1) for j in range(n + 1)}
    for i in range(1, m + 1):
        counts[(i, 0)] = np.ones(1)
        for j in range(1, n + 1):
            total = np.zeros(i * j + 1)
            total[j:] += counts[(i - 1, j)]  # the largest is one of the m: it beats all n
            total[:len(counts[(i, j - 1)])] += counts[(i, j - 1)]
            counts[(i, j)] = total
    null = counts[(m, n)] / counts[(m, n)].sum()
    null.flags.writeable = False
    return null


def rank_sum_p_value(ranks_by_experiment: list[np.ndarray], draws: int) -> float:
    """One-sided p-value of the summed ranks of the runs being as large as observed when
    every run is one more clean draw: the stratified Mann-Whitney test, exact (SciPy's
    ``mannwhitneyu`` is exact for one stratum only; the strata's counts add up here by
    convolving their null distributions).

    Args:
        ranks_by_experiment: per experiment and filter, the ranks of its runs (each the
            share of the same ``draws`` clean draws it exceeds, ties half); exchangeable
            within it (so correlated through those draws), independent across.
    Returns:
        P(sum of counts >= observed) under that null (the distribution of the sum by
        convolution; on the half-count grid that ties need).
    """
    total, observed = np.ones(1), 0
    for ranks in ranks_by_experiment:
        null = np.zeros(2 * len(ranks) * draws + 1)
        null[::2] = mann_whitney_null(len(ranks), draws)
        total = np.convolve(total, null)
        observed += int(np.rint(2 * draws * np.sum(ranks)))
    return float(np.clip(total[observed:].sum(), 0.0, 1.0))


def harmed_share_upper(ranks_by_experiment: list[np.ndarray], draws: int,
                       z: float = 1.645) -> float:
    """One-sided upper confidence bound (95 % for ``z = 1.645``) on the share of runs that
    end above every clean draw beyond what a clean draw does.

    The model: a share ``pi`` of the runs are harmed, each ranked 1 (above all ``draws``
    clean draws of its experiment), the rest are clean draws, ranked uniformly (mean 0.5),
    so the mean rank is ``0.5 + pi / 2``. The bound is ``2 (mean + z sd - 0.5)`` clipped to
    [0, 1], with ``sd`` the mean rank's standard deviation when every run is a clean draw:
    exact for the runs of one experiment sharing its clean draws (the Mann-Whitney count
    U of ``m`` runs against ``n`` draws has variance ``m n (m + n + 1) / 12``, so the
    experiment's summed ranks ``U / n`` have ``m (m + n + 1) / (12 n)``; ties ignored);
    runs pinned at rank 1 and ties only lower it, so the bound is conservative. A run
    harmed less than that (ranked below 1) is counted as a fraction of one.

    Args:
        ranks_by_experiment: as for :func:`rank_sum_p_value`.
    """
    runs = sum(len(r) for r in ranks_by_experiment)
    mean = sum(float(np.sum(r)) for r in ranks_by_experiment) / runs
    variance = sum(len(r) * (len(r) + draws + 1) / (12 * draws)
                   for r in ranks_by_experiment) / runs ** 2
    return float(np.clip(2 * (mean + z * np.sqrt(variance) - 0.5), 0.0, 1.0))
