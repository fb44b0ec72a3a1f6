"""DESPOT: the right first action and value where they are known, bounds that never cross,
a budget kept under a slow model, robust answers at degenerate roots, subtree reuse, and
memory that stays flat over a long run."""

import time

import numpy as np
import pytest

from planning.pomdp.benchmarks import tag, tiger
from planning.pomdp.despot import Despot, DespotSettings, belief_nodes
from planning.pomdp.generative import TabularGenerative
from planning.pomdp.online import DespotPlanner, run_episode, update_particles
from planning.pomdp.rocksample import RockSample
from planning.pomdp.tabular import belief_update
from planning.pomdp.tag import Tag
from planning.protocols import Planner


def finite_horizon_value(pomdp, belief, depth):
    """The exact optimal value of ``depth`` steps from ``belief``, by expectimax."""
    if depth == 0:
        return 0.0
    best = -np.inf
    for a in range(len(pomdp.actions)):
        value = float(belief @ pomdp.R[:, a])
        for o in range(len(pomdp.observations)):
            posterior, p = belief_update(pomdp, belief, a, o)
            if p > 1e-12:
                value += pomdp.discount * p * finite_horizon_value(pomdp, posterior, depth - 1)
        best = max(best, value)
    return best


@pytest.fixture(scope="module")
def tiger_model():
    return TabularGenerative(tiger())


def test_tiger_first_action_is_to_listen(tiger_model):
    rng = np.random.default_rng(0)
    planner = DespotPlanner(tiger_model, DespotSettings(scenarios=500, depth=30,
                                                        max_trials=300, seconds=60))
    assert isinstance(planner, Planner)
    result = planner.plan(tiger_model.sample_initial(1000, rng=rng), rng=rng)
    assert tiger_model.actions[result.action] == "listen"
    assert result.ranking[0] == result.action and sorted(result.ranking) == [0, 1, 2]
    assert result.stats["action_lower"][0] == max(result.stats["action_lower"])


@pytest.mark.parametrize("depth", [2, 4])
def test_a_searched_out_tree_has_the_exact_finite_horizon_value(tiger_model, depth):
    """Depth-limited Tiger: once the search closes the gap, the root's bound is the best
    depth-step policy's value on the scenarios, which K = 4000 puts near the exact one."""
    pomdp = tiger_model.pomdp
    exact = finite_horizon_value(pomdp, pomdp.initial, depth)
    rng = np.random.default_rng(1)
    search = Despot(tiger_model, DespotSettings(scenarios=4000, depth=depth, seconds=60,
                                                max_trials=10_000))
    action, stats, _ = search.search(tiger_model.sample_initial(4000, rng=rng), rng=rng)
    assert stats.upper - stats.lower < 1e-6
    assert stats.lower == pytest.approx(exact, abs=0.6)
    assert pomdp.actions[action] == "listen"


@pytest.mark.parametrize("variant, regularization", [("ar", 0.0), ("ar", 0.1), ("r", 0.0)])
@pytest.mark.parametrize("model", [Tag(), RockSample(7, 8)], ids=["tag", "rocksample"])
def test_bounds_never_cross_after_the_backups(model, variant, regularization):
    rng = np.random.default_rng(2)
    search = Despot(model, DespotSettings(scenarios=200, max_trials=60, seconds=60,
                                          variant=variant, regularization=regularization,
                                          engine="python"))
    _, stats, tree = search.search(model.sample_initial(500, rng=rng), rng=rng)
    nodes = list(belief_nodes(tree.root))
    assert len(nodes) == stats.nodes > 1
    for b in nodes:
        assert b.lower <= b.upper
        assert b.lower >= b.l0 - 1e-12
        for q in b.children or ():
            assert q.lower <= q.upper + 1e-9
    assert stats.lower <= stats.upper
    assert stats.policy_size <= stats.nodes


@pytest.mark.parametrize("regularization", [0.0, 0.1])
@pytest.mark.parametrize("model", [Tag(), RockSample(7, 8)], ids=["tag", "rocksample"])
def test_the_compiled_trees_bounds_never_cross(model, regularization):
    rng = np.random.default_rng(2)
    search = Despot(model, DespotSettings(scenarios=200, max_trials=60, seconds=60,
                                          regularization=regularization, engine="compiled"))
    _, stats, tree = search.search(model.sample_initial(500, rng=rng), rng=rng)
    arrays = tree.root
    n, q = int(arrays.counts[0]), int(arrays.counts[1])
    assert n == stats.nodes > 1 and stats.trials == 60
    assert np.all(arrays.lower[:n] <= arrays.upper[:n])
    assert np.all(arrays.lower[:n] >= arrays.l0[:n] - 1e-12)
    assert np.all(arrays.q_lower[:q] <= arrays.q_upper[:q] + 1e-9)
    assert stats.policy_size <= stats.nodes


@pytest.mark.parametrize("pomdp", [tiger, tag], ids=["tiger", "tag"])
@pytest.mark.parametrize("default_policy", ["blind", "qmdp"])
def test_the_compiled_search_is_the_python_search(pomdp, default_policy):
    """Same scenarios, same trials: the same tree, on tabular models (on the native Tag
    and RockSample the two engines sum rollouts in different orders, and exact ties
    between actions can then break either way, so only the bounds' consistency is
    compared there)."""
    tiger_model = TabularGenerative(pomdp(), default_policy=default_policy)
    particles = tiger_model.sample_initial(500, rng=np.random.default_rng(0))
    results = []
    for engine in ("python", "compiled"):
        search = Despot(tiger_model, DespotSettings(scenarios=200, max_trials=50, seconds=60,
                                                    engine=engine))
        results.append(search.search(particles, rng=np.random.default_rng(1))[:2])
    (a, python), (b, compiled) = results
    assert a == b and python.nodes == compiled.nodes and python.trials == compiled.trials
    assert compiled.lower == pytest.approx(python.lower, abs=1e-9)
    assert compiled.upper == pytest.approx(python.upper, abs=1e-9)
    np.testing.assert_allclose(compiled.action_lower, python.action_lower, atol=1e-9)


class SlowTag(Tag):
    """Tag whose step takes at least 3 ms: a model slower than the budget's grain."""

    def step(self, states, actions, u):
        time.sleep(0.003)
        return super().step(states, actions, u)


def test_the_wall_clock_budget_is_kept_to_within_one_trial():
    model = SlowTag()
    rng = np.random.default_rng(3)
    search = Despot(model, DespotSettings(seconds=0.15, engine="python"))
    _, stats, _ = search.search(model.sample_initial(500, rng=rng), rng=rng)
    assert stats.trials >= 1
    assert stats.seconds <= 0.15 + stats.trial_ms_max / 1e3 + 0.005
    assert stats.overrun_ms == pytest.approx(max(0.0, (stats.seconds - 0.15) * 1e3))


def test_qmdp_rollouts_bound_tiger_better_than_the_blind_policy():
    """Tiger's blind policy listens forever (-20 over 90 steps); rolling out QMDP on the
    node's scenarios opens a door when they agree, a far tighter lower bound."""
    bounds = {}
    for policy in ("blind", "qmdp"):
        model = TabularGenerative(tiger(), default_policy=policy)
        rng = np.random.default_rng(0)
        search = Despot(model, DespotSettings(scenarios=300, max_trials=30, seconds=60))
        bounds[policy] = search.search(model.sample_initial(500, rng=rng), rng=rng)[1].lower
    assert bounds["qmdp"] > bounds["blind"] + 5.0
    with pytest.raises(ValueError, match="default_policy"):
        TabularGenerative(tiger(), default_policy="random")


def test_the_compiled_engine_says_when_it_does_not_apply(tiger_model):
    with pytest.raises(ValueError, match="compiled engine"):
        Despot(tiger_model, DespotSettings(engine="compiled", variant="r"))
    with pytest.raises(ValueError, match="engine must be"):
        DespotSettings(engine="gpu")


def test_degenerate_roots_still_give_the_default_policys_action(tiger_model):
    rng = np.random.default_rng(4)
    particles = tiger_model.sample_initial(100, rng=rng)
    no_time = Despot(tiger_model, DespotSettings(max_trials=0))
    action, stats, _ = no_time.search(particles, rng=rng)
    assert stats.trials == 0 and action == tiger_model.default_actions(particles[:1])[0]
    infinite = Despot(tiger_model, DespotSettings(max_trials=5),
                      upper_bound=lambda states: np.full(len(states), np.inf))
    action, stats, _ = infinite.search(particles, rng=rng)
    assert action in (0, 1, 2)


def test_terminal_states_end_the_search_and_the_episode():
    model = RockSample(5, 3)
    exited = np.array([[5, 2, 0]] * 10)
    for engine in ("python", "compiled"):
        search = Despot(model, DespotSettings(max_trials=10, engine=engine))
        _, stats, _ = search.search(exited, rng=np.random.default_rng(5))
        assert stats.trials == 0 and stats.nodes == 1
        assert stats.lower == stats.upper == 0.0
    episode = run_episode(model, DespotPlanner(model, DespotSettings(scenarios=100,
                                                                     max_trials=20)),
                          rng=np.random.default_rng(6), steps=60, particles=200)
    assert episode.steps < 60  # it exits


def test_subtree_reuse_rescales_the_kept_tree():
    model = Tag()
    planner = DespotPlanner(model, DespotSettings(scenarios=300, max_trials=40, seconds=60,
                                                  reuse="subtree", reuse_min_fraction=0.0))
    rng = np.random.default_rng(7)
    belief = model.sample_initial(500, rng=rng)
    first = planner.plan(belief, rng=rng)
    state = model.sample_initial(1, rng=rng)
    step = model.step(state, first.action, rng.random((1, 1)))
    observation = int(step.observations[0])
    belief, weights, _ = update_particles(model, belief, first.action, observation, rng=rng)
    second = planner.plan(belief, rng=rng, memory=first.memory, observation=observation,
                          weights=weights)
    assert second.stats["reused"]
    root = second.memory.tree.root
    assert root.depth == 0 and len(root.scenarios) == second.memory.tree.scenarios
    for b in belief_nodes(root):
        assert b.lower <= b.upper + 1e-12


def test_the_belief_recovers_when_no_particle_explains_the_observation():
    model = Tag()
    rng = np.random.default_rng(8)
    particles = np.array([[0, 5]] * 50)  # robot in cell 0: "robot at 20" is impossible
    updated, weights, recovered = update_particles(model, particles, 4, 20, rng=rng)
    assert recovered and updated.shape == particles.shape
    np.testing.assert_allclose(weights, 1 / 50)


def test_the_belief_is_exact_bayes_on_deterministic_transitions_until_it_resamples():
    """RockSample's rocks never change: after one noisy check the weights are the
    posterior's and every configuration is kept (the effective sample size stays above
    half); a run of checks that all say "good" ends in a resampled set of equal weights."""
    model = RockSample(7, 8)
    rng = np.random.default_rng(10)
    particles = model.sample_initial(400, rng=rng)
    check = model.actions.index("check0")
    good = (particles[:, 2] & 1) == 1
    updated, weights, recovered = update_particles(model, particles, check, 1, rng=rng)
    assert not recovered
    np.testing.assert_array_equal(updated, particles)  # not resampled
    expected = np.exp(model.log_likelihood(1, particles, check))
    np.testing.assert_allclose(weights, expected / expected.sum())
    assert weights[good].min() > weights[~good].max()
    for step in range(10):  # rocks 0 and 1 good, again and again: a quarter of the set
        rock = model.actions.index(f"check{step % 2}")
        updated, weights, recovered = update_particles(model, updated, rock, 1, rng=rng,
                                                       weights=weights)
        if 1 / np.sum(weights ** 2) < 400 / 2:
            raise AssertionError("the set should have been resampled")
        if np.all(weights == weights[0]):
            break
    np.testing.assert_allclose(weights, 1 / 400)  # resampled once the ESS fell below half
    assert np.mean((updated[:, 2] & 3) == 3) > 0.9


def resident_mb() -> float:
    """The process' current resident memory (MB), from /proc (numba's arrays included,
    which tracemalloc does not see)."""
    import os

    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


@pytest.mark.slow
@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_memory_stays_flat_over_a_thousand_decisions(engine):
    model = Tag()
    planner = DespotPlanner(model, DespotSettings(scenarios=200, max_trials=15, seconds=60,
                                                  engine=engine))
    rng = np.random.default_rng(9)
    sizes, decisions = [], 0
    while decisions < 1000:
        episode = run_episode(model, planner, rng=rng, steps=90, particles=300)
        decisions += episode.steps
        sizes.append((decisions, resident_mb(), planner.search.workspace_bytes))
    # the compiled engine's workspace grows (by doubling) to the largest tree seen and is
    # kept; what must not grow is everything else: the resident memory added between
    # episodes in which the workspace stayed the same size, after the first 150 decisions
    growth = sum(b[1] - a[1] for a, b in zip(sizes, sizes[1:], strict=False)
                 if a[0] >= 150 and a[2] == b[2])
    assert growth < 5.0  # MB over some 850 decisions
