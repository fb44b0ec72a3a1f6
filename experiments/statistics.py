"""Small statistics shared by the studies."""

from __future__ import annotations

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


def holm(p_values: dict, level: float = 0.05) -> dict:
    """Holm's step-down test over ``p_values`` (key -> p): key -> rejected at ``level``
    with the family-wise error rate held."""
    rejected, still = {}, True
    for i, (key, p) in enumerate(sorted(p_values.items(), key=lambda item: item[1])):
        still = still and p <= level / (len(p_values) - i)
        rejected[key] = still
    return rejected
