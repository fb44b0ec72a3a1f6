"""The hand-relative problem on the continuous planar model as a generative POMDP, and
DESPOT planning on it."""

import numpy as np
import pytest

from models.planar.world import PlanarWorld
from planning.hand.beliefs import GaussianBelief
from planning.hand.discretization import HandProblemSpec
from planning.hand.generative import ContinuousHandGenerative
from planning.hand.model import build_hand_pomdp
from planning.pomdp.despot import Despot, DespotSettings
from planning.pomdp.generative import GenerativePOMDP
from planning.pomdp.online import DespotPlanner

BELIEF = GaussianBelief((0.15, 0.0, 0.0), (0.005, 0.05, np.pi))


@pytest.fixture(scope="module")
def small_model():
    """The ch. 7 kind of problem (four moves, one grid) at 2 cm over a narrow region."""
    world = PlanarWorld.load("bottle", sensors="fingertips", error_rate=0.0)
    spec = HandProblemSpec(trust_x_m=(0.0, 0.20), trust_y_m=(-0.06, 0.06),
                           free_cell_m=0.02, contact_states=False, step_m=0.02,
                           action_names=("forward", "back", "left", "right"),
                           action_directions=((1, 0), (-1, 0), (0, 1), (0, -1)),
                           samples_per_state=6)
    return build_hand_pomdp(world, spec, rng=np.random.default_rng(0), progress=False)


@pytest.fixture(scope="module")
def generative(small_model):
    return ContinuousHandGenerative(small_model, BELIEF)


def test_steps_are_the_planar_worlds_and_deterministic_given_u(small_model, generative):
    g, world = generative, small_model.world
    assert isinstance(g, GenerativePOMDP)
    rng = np.random.default_rng(1)
    states = g.sample_initial(64, rng=rng)
    actions = rng.integers(0, len(g.actions), 64)
    u = rng.random((64, g.uniforms_per_step))
    step = g.step(states, actions, u)
    again = g.step(states, actions, u)
    np.testing.assert_array_equal(step.next_states, again.next_states)
    np.testing.assert_array_equal(step.observations, again.observations)
    for a in range(len(g.actions)):  # each row as the world pushes it alone
        rows = np.flatnonzero(actions == a)
        width = world.uniforms_per_step(g.vectors[a])
        np.testing.assert_allclose(step.next_states[rows],
                                   world.step(states[rows], g.vectors[a], u[rows, :width]))
    np.testing.assert_array_equal(step.rewards, small_model.in_goal(states) - 1.0)
    assert not step.terminal.any()
    touching = world.sensing.readings(step.next_states)[1]  # perfect sensors
    np.testing.assert_array_equal(step.observations, touching @ (1 << np.arange(2)))
    for o in np.unique(step.observations):  # what was read is possible, nothing else is
        rows = step.observations == o
        likelihood = g.log_likelihood(int(o), step.next_states, 0)
        assert np.isfinite(likelihood[rows]).all()
        assert not np.isfinite(likelihood[~rows]).any()


def test_bounds_and_rollout_policy_are_rel_qmdps(small_model, generative):
    g = generative
    states = g.sample_initial(50, rng=np.random.default_rng(2))
    cells = small_model.index(states)
    q = g._tabular._q
    np.testing.assert_allclose(g.upper_bound(states), q[cells].max(axis=1))
    actions = g.default_actions(states)
    assert (actions == np.argmax(q[cells].sum(axis=0))).all()


def test_the_search_steps_every_node_of_a_rollout_together(small_model):
    """The Python engine's rollout (all nodes stepped at once) equals each node's rollout
    stepped alone, depth by depth, with the node's QMDP action."""
    g = ContinuousHandGenerative(small_model, BELIEF, rollout="continuous")
    search = Despot(g, DespotSettings(scenarios=12, depth=6))
    rng = np.random.default_rng(3)
    search._uniforms = rng.random((12, 7, g.uniforms_per_step))
    search._k = 12
    states = g.sample_initial(12, rng=rng)
    scenarios = np.arange(12)
    offsets = np.array([0, 5, 12])
    depths = np.array([2] * 5 + [4] * 7)
    values = search._rollout(states, scenarios, np.zeros(12, dtype=bool), depths, offsets)
    for lo, hi in zip(offsets[:-1], offsets[1:], strict=True):
        node, expected, scale = states[lo:hi].copy(), np.zeros(hi - lo), 1.0
        for depth in range(depths[lo], 6):
            step = g.step(node, g.default_actions(node)[0],
                          search._uniforms[scenarios[lo:hi], depth])
            expected += scale * step.rewards
            node, scale = step.next_states, scale * g.discount
        np.testing.assert_allclose(values[lo:hi], expected)


@pytest.mark.parametrize("rollout", ["discrete", "continuous"])
def test_despot_plans_on_the_continuous_model(small_model, rollout):
    """At depth 90: shallower, a -1-a-step rollout beats the infinite-horizon bound."""
    g = ContinuousHandGenerative(small_model, BELIEF, rollout=rollout)
    planner = DespotPlanner(g, DespotSettings(scenarios=20, depth=90, max_trials=8,
                                              seconds=30.0))
    particles = g.sample_initial(200, rng=np.random.default_rng(4))
    result = planner.plan(particles, rng=np.random.default_rng(5))
    assert 0 <= result.action < len(g.actions)
    assert sorted(result.ranking) == list(range(len(g.actions)))
    stats = result.stats
    assert stats["trials"] >= 1 and stats["nodes"] > 1
    assert stats["lower"] <= stats["upper"]
    assert np.isfinite(stats["action_lower"]).all()


def test_unknown_rollouts_are_refused(small_model):
    with pytest.raises(ValueError, match="rollout must be one of"):
        ContinuousHandGenerative(small_model, BELIEF, rollout="fast")
