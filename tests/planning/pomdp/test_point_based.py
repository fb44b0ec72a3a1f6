"""The point-based solver: valid, converging bounds; a policy that acts and round-trips."""

import numpy as np
import pytest

from planning.pomdp.benchmarks import tag, tiger
from planning.pomdp.point_based import AlphaVectorPolicy, LookaheadPolicy, PointBasedSolver
from planning.pomdp.tabular import simulate_value

TIGER_OPTIMUM = 19.37  # infinite-horizon value of Tiger at the uniform belief, discount 0.95


def test_tiger_bounds_close_on_the_optimum():
    solver = PointBasedSolver(tiger())
    solver.solve(120.0, max_trials=1000)  # trials, not seconds: the JIT may compile first
    lower, upper = solver.report.history[-1][1:]
    assert lower <= TIGER_OPTIMUM + 0.01 and upper >= TIGER_OPTIMUM - 0.01
    assert upper - lower < 0.05
    uppers = [row[2] for row in solver.report.history]
    assert all(b <= a + 1e-9 for a, b in zip(uppers, uppers[1:], strict=False))


def test_tag_lower_bound_is_a_value_the_policy_achieves(tmp_path):
    model = tag()
    solver = PointBasedSolver(model)
    policy = solver.solve(120.0, max_trials=100)
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
    policy = LookaheadPolicy(model, PointBasedSolver(model).solve(60.0, max_trials=200))
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
    policy = solver.solve(60.0, initial_beliefs=np.stack([left, right]), weights=[1, 3],
                          max_trials=500)
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
    solver.solve(60.0, max_trials=40)
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


@pytest.mark.parametrize("rule", PointBasedSolver.TRIAL_RULES)
def test_both_trial_rules_close_tiger_on_the_optimum(rule):
    solver = PointBasedSolver(tiger(), trial_rule=rule)
    solver.solve(120.0, max_trials=1000)
    lower, upper = solver.report.history[-1][1:]
    assert lower <= TIGER_OPTIMUM + 0.01 and upper >= TIGER_OPTIMUM - 0.01
    assert upper - lower < 0.05


def test_sarsop_child_target_is_what_the_parent_needs():
    """With the chosen child at its target and the others at their values, the parent's
    one-step value is exactly the parent's target."""
    from planning.pomdp.point_based import _child_target

    p, values = np.array([0.2, 0.0, 0.8]), np.array([3.0, -np.inf, 5.0])
    target, reward, gamma = 7.0, 1.5, 0.95
    child = _child_target(target, reward, p, values, 2, gamma)
    assert reward + gamma * (p[0] * values[0] + p[2] * child) == pytest.approx(target)


def test_solver_settings_are_checked():
    with pytest.raises(ValueError, match="trial_rule must be one of"):
        PointBasedSolver(tiger(), trial_rule="greedy")
    with pytest.raises(ValueError, match="kappa"):
        PointBasedSolver(tiger(), kappa=0.0)


def test_first_pruning_keeps_the_best_vector_at_every_visited_belief():
    """The first pruning has no remembered bests: every belief meets every vector."""
    solver = PointBasedSolver(tag(), prune_every=10**9)
    solver.solve(60.0, max_trials=15)
    assert solver._best_value.size == 0 and len(solver.alphas) > 5
    before = [solver.lower(_dense(solver, sup, p)) for sup, p in solver.visited]
    solver._prune()
    after = [solver.lower(_dense(solver, sup, p)) for sup, p in solver.visited]
    np.testing.assert_allclose(after, before, rtol=0, atol=1e-9)


@pytest.mark.parametrize("keep_subplans", [False, True])
def test_pruning_never_lowers_the_root_bound(keep_subplans):
    """The root is visited by every trial, so its bound (the reported lower bound) can only
    rise however often the vectors are pruned; with ``keep_subplans`` every kept vector's
    plan is kept too."""
    solver = PointBasedSolver(tag(), prune_every=10, keep_subplans=keep_subplans)
    solver.solve(60.0, max_trials=60, report_every=0.0)
    lowers = [row[1] for row in solver.report.history]
    assert all(b >= a - 1e-9 for a, b in zip(lowers, lowers[1:], strict=False))
    assert lowers[-1] > lowers[0]
    children = solver.store.children
    if keep_subplans:
        assert children.min() >= 0 and children.max() < len(solver.alphas)
    else:
        assert children.min() == -1  # some plans were pruned
    with pytest.raises(ValueError, match="prune_every"):
        PointBasedSolver(tiger(), prune_every=0)


def test_sawtooth_correction_matches_the_formula():
    """The chained point store and its compiled reader against the sawtooth written out:
    min(0, min_i excess_i min_{s in supp b_i} b(s) / b_i(s))."""
    from planning.pomdp.point_based import _UpperPoints

    rng = np.random.default_rng(5)
    n_states = 30
    points = _UpperPoints(n_states)
    stored = []
    for _ in range(200):  # grows the flat storage several times
        support = np.sort(rng.choice(n_states, size=rng.integers(1, 6), replace=False))
        probs = rng.dirichlet(np.ones(len(support)))
        excess = -rng.random()
        points.add(support, probs, excess)
        stored.append((support, probs, excess))
    for key in range(n_states):  # each chain runs from the most negative excess
        i, chain = points.head[key], []
        while i >= 0:
            chain.append(points.excess[i])
            i = points.next[i]
        assert chain == sorted(chain)
    scratch = np.zeros(n_states)
    for _ in range(50):
        support = np.sort(rng.choice(n_states, size=rng.integers(1, 20), replace=False))
        beliefs = rng.dirichlet(np.ones(len(support)), size=3)
        got = points.correction(support, beliefs, scratch)
        for belief, value in zip(beliefs, got, strict=True):
            dense = np.zeros(n_states)
            dense[support] = belief
            expected = min([0.0] + [e * np.min(dense[s] / p) for s, p, e in stored])
            assert value == pytest.approx(expected, abs=1e-12)
        assert not scratch.any()


def _dense(solver, support, probs):
    belief = np.zeros(solver.m.shape[0])
    belief[support] = probs
    return belief
