"""Weighted A* over no-contact beliefs and the combined policy."""

import numpy as np
import pytest

from planning.hand.beliefs import GaussianBelief
from planning.hand.policy import HandPolicy, qmdp_vectors
from planning.hand.precontact import PreContactPlan, PreContactPlanner, PreContactSettings
from planning.pomdp.qmdp import solve_mdp


@pytest.fixture(scope="module")
def qmdp(small_hand_model):
    return qmdp_vectors(solve_mdp(small_hand_model.pomdp), small_hand_model.pomdp.actions)


def test_heuristic_never_promises_less_than_the_mdp_achieves(small_hand_model, qmdp):
    """Vbar bounds the discrete MDP's optimal value from above, cell for cell, once the
    distance is measured from the cell's nearest point (half a diagonal closer)."""
    m = small_hand_model
    planner = PreContactPlanner(m, qmdp)
    poses = m.discretization.representative_poses()
    states = m.index(poses)
    mdp_value = qmdp.alphas.max(axis=0)  # V_MDP(s) = max_a Q(s, a)
    free = states < m.free_count
    towards_goal = poses[free].copy()
    towards_goal[:, 0] -= m.spec.free_cell_m / 2
    towards_goal[:, 1] -= np.sign(towards_goal[:, 1]) * m.spec.free_cell_m / 2
    bound = planner.heuristic_values(towards_goal)
    assert (mdp_value[states[free]] <= bound + 1e-9).all()
    assert (planner.heuristic_values(poses) <= 0).all()


def test_search_from_far_ahead_moves_forward_until_the_belief_is_in_the_trust_region(
        small_hand_model, qmdp):
    m = small_hand_model
    planner = PreContactPlanner(m, qmdp, PreContactSettings(time_limit_s=10.0))
    rng = np.random.default_rng(0)
    particles = GaussianBelief((0.40, 0.03, 0.0), (0.02, 0.02, 0.2)).sample(m.world, 100,
                                                                            rng=rng)
    plan = planner.plan(particles, rng=rng)
    assert plan.reason == "trust_region"
    forward_m = sum(m.spec.action_vectors()[a][0] for a in plan.actions)
    assert forward_m >= 0.40 - 0.22  # the mean must come inside the 22 cm region
    assert plan.cost > 0 and plan.expansions >= len(plan.actions)


def test_search_stops_at_once_inside_the_trust_region(small_hand_model, qmdp):
    m = small_hand_model
    planner = PreContactPlanner(m, qmdp)
    particles = GaussianBelief((0.17, 0.0, 0.0), (0.005, 0.005, 0.05)).sample(
        m.world, 50, rng=np.random.default_rng(1))
    plan = planner.plan(particles, rng=np.random.default_rng(2))
    assert plan.actions == () and plan.reason == "trust_region"


def test_policy_switches_to_the_discrete_filter_on_contact(small_hand_model, qmdp):
    m = small_hand_model
    policy = HandPolicy(m, qmdp, PreContactPlanner(m, qmdp))
    rng = np.random.default_rng(3)
    # 1.5 cm beyond the F1/F2 fingertip, squarely: a forward step pushes it
    particles = GaussianBelief((0.15, -0.01, 0.0), (0.003, 0.003, 0.05)).sample(
        m.world, 80, rng=rng)
    plan = PreContactPlan((0, 0, 0), 0.0, 0, 0.0, "given")
    policy.reset(particles, plan=plan, rng=rng)
    assert policy.phase == "pre-contact"
    a = policy.act()
    assert a == policy.plan.actions[0]
    policy.observe(a, np.array([True, False]), rng=rng)  # sensor 0 fires
    assert policy.phase == "post-contact"
    b = policy.discrete
    assert b.sum() == pytest.approx(1.0)
    assert b[m.pomdp.Z[a, :, 1] == 0].sum() == 0  # only states that can read it
    assert 0 <= policy.act() < 5


def test_post_contact_policy_alone_acts_on_a_discrete_belief(small_hand_model, qmdp):
    m = small_hand_model
    policy = HandPolicy(m, qmdp)
    b = m.belief(np.array([[0.19, 0.05, 0.0]]))
    policy.reset(b, rng=np.random.default_rng(0))
    assert policy.phase == "post-contact"
    assert policy.act() == qmdp.act(b)
    policy.observe(policy.act(), np.array([False, False]), rng=np.random.default_rng(0))
    assert policy.discrete.sum() == pytest.approx(1.0)


def test_time_limit_returns_the_frontier_path_not_the_root(small_hand_model, qmdp):
    m = small_hand_model
    settings = PreContactSettings(time_limit_s=1e-9, trust_mass_stop=None)
    planner = PreContactPlanner(m, qmdp, settings)
    particles = GaussianBelief((0.40, 0.0, 0.0), (0.02, 0.02, 0.2)).sample(
        m.world, 30, rng=np.random.default_rng(4))
    plan = planner.plan(particles, rng=np.random.default_rng(5))
    assert plan.reason == "time_limit" and len(plan.actions) == 1


def test_act_on_a_new_belief_needs_a_generator(small_hand_model, qmdp):
    m = small_hand_model
    policy = HandPolicy(m, qmdp)
    b = m.belief(np.array([[0.19, 0.05, 0.0]]))
    with pytest.raises(ValueError, match="rng"):
        policy.act(b)
    assert policy.act(b, rng=np.random.default_rng(0)) == qmdp.act(b)


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="trust_mass_stop"):
        PreContactSettings(trust_mass_stop=1.5)
    with pytest.raises(ValueError, match="inflation"):
        PreContactSettings(inflation=0.5)
