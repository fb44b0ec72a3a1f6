"""The one way the benches time a call: the median of repeated calls, after a warm-up."""

from __future__ import annotations

import time

import numpy as np
from tqdm import tqdm


def median_ms(fn, repeats: int, label: str | None = None) -> float:
    """Median wall time (ms) of ``repeats`` calls of ``fn()``, after one untimed call (JIT
    compilation, caches); a progress bar when ``label`` is given."""
    fn()
    times = []
    for _ in tqdm(range(repeats), desc=label, leave=False, disable=label is None):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3)
