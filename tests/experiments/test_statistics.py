"""The studies' intervals and tests."""

import numpy as np
import pytest

from experiments.statistics import (
    clustered_half_width,
    half_width,
    harmed_share_upper,
    holm,
    mann_whitney_null,
    rank_sum_p_value,
    wilson_interval,
)


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


def test_the_mann_whitney_null_counts_the_orderings():
    assert mann_whitney_null(1, 5) == pytest.approx(np.full(6, 1 / 6))
    assert mann_whitney_null(2, 2) == pytest.approx(np.array([1, 1, 2, 1, 1]) / 6)
    null = mann_whitney_null(6, 5)
    assert len(null) == 31 and null.sum() == pytest.approx(1.0)
    assert null == pytest.approx(null[::-1])  # symmetric about m n / 2


def test_the_stratified_rank_test_is_exact_and_holds_its_level_on_clean_draws():
    assert rank_sum_p_value([np.array([0.0])], 5) == pytest.approx(1.0)
    assert rank_sum_p_value([np.array([1.0])], 5) == pytest.approx(1 / 6)
    assert rank_sum_p_value([np.array([1.0]), np.array([1.0])], 5) == pytest.approx(1 / 36)
    assert rank_sum_p_value([np.array([0.9])], 5) == pytest.approx(1 / 6)  # a tie at 0.9
    assert rank_sum_p_value([np.array([1.0, 1.0])], 5) == pytest.approx(1 / 21)  # C(7, 2)
    # experiments of 6 runs, each ranked against the same 5 clean draws: all 11 exchangeable
    rng = np.random.default_rng(0)
    draws = rng.normal(size=(600, 6, 11))
    ranks = np.mean(draws[..., :6, None] > draws[..., None, 6:], axis=-1)  # (600, 6, 6)
    p = [rank_sum_p_value(list(group), 5) for group in ranks]  # 600 groups of 6 experiments
    assert 0.01 <= np.mean(np.array(p) < 0.05) <= 0.07
    assert rank_sum_p_value([np.full(6, 0.8)] * 6, 5) < 1e-3


def test_the_harmed_share_bound_covers_the_share_of_runs_a_fault_left_above_its_draws():
    # 6 experiments of 6 runs, each against the same 11 clean draws, a share of the runs
    # harmed: ranked above all the draws; the rest exchangeable with them
    rng = np.random.default_rng(2)
    values = rng.normal(size=(400, 6, 17))
    harmed = rng.uniform(size=(400, 6, 6)) < 0.2
    values[..., :6] = np.where(harmed, np.inf, values[..., :6])
    ranks = np.mean(values[..., :6, None] > values[..., None, 6:], axis=-1)  # (400, 6, 6)
    bounds = np.array([harmed_share_upper(list(group), 11) for group in ranks])
    assert np.mean(bounds >= harmed.mean(axis=(1, 2))) >= 0.93  # one-sided 95 %
    clean = np.array([harmed_share_upper(list(group), 11)
                      for group in np.mean(rng.normal(size=(400, 6, 6, 1))
                                           > rng.normal(size=(400, 6, 1, 11)), axis=-1)])
    assert 0.1 < np.median(clean) < 0.35 and clean.min() >= 0.0
    assert harmed_share_upper([np.ones(6)] * 6, 11) == 1.0
    assert harmed_share_upper([np.zeros(6)] * 6, 11) == 0.0


def test_the_clustered_half_width_covers_means_of_runs_that_share_their_draws():
    # groups of 6 values sharing a group effect: the iid half-width is too narrow
    rng = np.random.default_rng(3)
    values = rng.normal(size=(2000, 12, 1)) + rng.normal(size=(2000, 12, 6))
    clustered = np.array([clustered_half_width(list(v)) for v in values])
    iid = np.array([half_width(v.ravel()) for v in values])
    covered = np.abs(values.mean(axis=(1, 2))) <= clustered
    assert 0.89 <= covered.mean() <= 0.97  # 12 groups, normal quantile: a little below 95 %
    assert np.mean(np.abs(values.mean(axis=(1, 2))) <= iid) < 0.8
    assert clustered_half_width([np.ones(3)]) == 0.0
    assert clustered_half_width([np.ones(3), np.ones(2)]) == 0.0
