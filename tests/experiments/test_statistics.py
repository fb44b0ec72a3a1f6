"""The studies' intervals."""

import numpy as np
import pytest

from experiments.statistics import half_width, holm, wilson_interval


def test_wilson_interval_stays_in_the_unit_interval_and_matches_the_formula():
    for n in (3, 40, 200):
        lo, hi = wilson_interval(0, n)
        assert lo == 0.0 and 0.0 < hi < 1.0  # printed as 0 %, not -0 %
        lo, hi = wilson_interval(n, n)
        assert 0.0 < lo < 1.0 and hi == 1.0
    lo, hi = wilson_interval(20, 30)  # textbook value: [0.488, 0.808]
    assert lo == pytest.approx(0.4878, abs=1e-3) and hi == pytest.approx(0.8077, abs=1e-3)


def test_half_width_is_the_normal_interval_of_the_mean():
    values = np.array([1.0, 2.0, 3.0, 4.0])
    assert half_width(values) == pytest.approx(1.96 * values.std(ddof=1) / 2)
    assert half_width(np.array([5.0])) == 0.0


def test_holm_steps_down_from_the_smallest_p_value():
    # 0.01 <= 0.05 / 3, 0.02 <= 0.05 / 2, 0.04 <= 0.05 / 1
    assert holm({"a": 0.01, "b": 0.02, "c": 0.04}) == {"a": True, "b": True, "c": True}
    # 0.01 <= 0.05 / 3, then 0.026 > 0.05 / 2 stops the steps: b is not rejected either
    assert holm({"a": 0.01, "b": 0.03, "c": 0.026}) == {"a": True, "b": False, "c": False}
    assert holm({"a": 0.5}) == {"a": False}
