"""The point-based solver: valid, converging bounds; a policy that acts and round-trips."""

import numpy as np
import pytest

from planning.benchmarks import tag, tiger
from planning.point_based import AlphaVectorPolicy, LookaheadPolicy, PointBasedSolver
from planning.pomdp import simulate_value

TIGER_OPTIMUM = 19.37  # infinite-horizon value of Tiger at the uniform belief, discount 0.95


def test_tiger_bounds_close_on_the_optimum():
    solver = PointBasedSolver(tiger())
    solver.solve(10.0)
    lower, upper = solver.report.history[-1][1:]
    assert lower <= TIGER_OPTIMUM + 0.01 and upper >= TIGER_OPTIMUM - 0.01
    assert upper - lower < 0.05
    uppers = [row[2] for row in solver.report.history]
    assert all(b <= a + 1e-9 for a, b in zip(uppers, uppers[1:], strict=False))


def test_tag_lower_bound_is_a_value_the_policy_achieves(tmp_path):
    model = tag()
    solver = PointBasedSolver(model)
    policy = solver.solve(8.0)
    lower, upper = solver.report.history[-1][1:]
    assert -20.0 < lower < upper
    value, half = simulate_value(model, policy, 200, 90, rng=np.random.default_rng(3))
    assert value > lower - 3 * half - 0.5  # a lower bound, up to simulation noise
    path = tmp_path / "tag_policy.npz"
    policy.save(path)
    loaded = AlphaVectorPolicy.load(path)
    b = model.initial
    assert loaded.act(b) == policy.act(b) and loaded.value(b) == pytest.approx(policy.value(b))


def test_lookahead_policy_on_tiger_listens_when_unsure():
    model = tiger()
    policy = LookaheadPolicy(model, PointBasedSolver(model).solve(3.0))
    assert policy.act(model.initial) == 0  # listen
    assert policy.act(np.array([0.999, 0.001])) == 2  # open the other door
    value, _ = simulate_value(model, policy, 400, 100, rng=np.random.default_rng(0))
    assert value > TIGER_OPTIMUM - 3.0


def test_several_initial_beliefs_are_planned_for_together():
    """The augmented POMDP of thesis sec. 6.2.1: bounds are the weighted sums over the
    initial beliefs, and the one policy is good at each of them."""
    model = tiger()
    left, right = np.array([0.85, 0.15]), np.array([0.15, 0.85])
    solver = PointBasedSolver(model)
    policy = solver.solve(3.0, initial_beliefs=np.stack([left, right]), weights=[1, 3])
    lower, upper = solver.report.history[-1][1:]
    assert lower == pytest.approx(0.25 * solver.lower(left) + 0.75 * solver.lower(right))
    assert upper - lower < 0.1
    assert policy.value(left) == pytest.approx(solver.lower(left))
    with pytest.raises(ValueError, match="columns"):
        solver.solve(1.0, initial_beliefs=np.ones((1, 3)) / 3)


def test_incremental_pruning_keeps_the_best_vector_at_every_visited_belief():
    """Pruning compares only what changed since the last pruning; the bound at every
    visited belief must be what all the vectors together give."""
    import scipy.sparse as sp

    solver = PointBasedSolver(tag(), prune_every=25)
    solver.solve(3.0)
    S = solver.m.shape[0]
    rows = np.concatenate([np.full(len(sup), i) for i, (sup, _) in enumerate(solver.visited)])
    B = sp.csr_matrix((np.concatenate([p for _, p in solver.visited]),
                       (rows, np.concatenate([sup for sup, _ in solver.visited]))),
                      shape=(len(solver.visited), S))
    before = np.asarray(B @ solver.alphas.T).max(axis=1)
    solver._prune()
    values = np.asarray(B @ solver.alphas.T)
    np.testing.assert_allclose(values.max(axis=1), before, rtol=0, atol=1e-9)
    np.testing.assert_allclose(solver._best_value, before, rtol=0, atol=1e-9)
    remembered = values[np.arange(len(values)), solver._best_index]
    np.testing.assert_allclose(remembered, before, rtol=0, atol=1e-9)
