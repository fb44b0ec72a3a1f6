"""The closed loop's planner: pre-contact trajectory, then the post-contact vectors on the
estimator's particle belief; and the solved-model cache."""

import numpy as np
import pytest

from estimation.particles.belief import ParticleBelief
from planning.hand.beliefs import GaussianBelief
from planning.hand.planner import HandPlanner, ThesisHandPlanner
from planning.hand.policy import qmdp_vectors
from planning.hand.precontact import PreContactSettings
from planning.hand.solution import HandSolveSettings, solve_hand_problem
from planning.pomdp.point_based import AlphaVectorPolicy
from planning.pomdp.qmdp import solve_mdp
from planning.protocols import Planner


@pytest.fixture(scope="module")
def qmdp(small_hand_model):
    return qmdp_vectors(solve_mdp(small_hand_model.pomdp), small_hand_model.pomdp.actions)


def _belief(model, mean, n=100, seed=0):
    states = GaussianBelief(mean, (0.02, 0.02, 0.2)).sample(model.world, n,
                                                           rng=np.random.default_rng(seed))
    return ParticleBelief.uniform(states)


def test_action_values_rank_by_the_best_vector_of_each_action():
    policy = AlphaVectorPolicy(np.array([[1.0, 0.0], [0.0, 2.0], [0.5, 0.5]]),
                               np.array([0, 0, 2]), ("a", "b", "c"))
    values = policy.action_values(np.array([0.5, 0.5]))
    np.testing.assert_allclose(values, [1.0, -np.inf, 0.5])
    assert policy.act(np.array([0.5, 0.5])) == int(np.argmax(values))


def test_far_belief_follows_the_searched_trajectory_then_the_vectors(small_hand_model, qmdp):
    m = small_hand_model
    planner = HandPlanner(m, qmdp, PreContactSettings(time_limit_s=5.0))
    belief = _belief(m, (0.40, 0.0, 0.0))
    rng = np.random.default_rng(1)
    result = planner.plan(belief, contact_seen=False, rng=rng)
    assert isinstance(planner, Planner)
    trajectory = result.memory.trajectory.actions
    assert len(trajectory) >= 1 and result.action == trajectory[0]
    assert result.phase == "pre-contact" and "search" in result.stats
    assert sorted(result.ranking) == list(range(5)) and result.ranking[0] == result.action
    first = result
    for expected in trajectory[1:]:
        result = planner.plan(belief, contact_seen=False, rng=rng, memory=result.memory)
        assert result.action == expected and "search" not in result.stats
    result = planner.plan(belief, contact_seen=False, rng=rng, memory=result.memory)
    assert result.phase == "post-contact"
    assert result.action == qmdp.act(m.belief(belief.states, belief.weights))
    # the planner itself remembers nothing: the first answer's memory replays the second
    again = planner.plan(belief, contact_seen=False, rng=rng, memory=first.memory)
    assert again.action == (trajectory[1] if len(trajectory) > 1 else result.action)


def test_contact_switches_to_the_post_contact_policy_for_good(small_hand_model, qmdp):
    m = small_hand_model
    planner = HandPlanner(m, qmdp, PreContactSettings(time_limit_s=5.0))
    belief = _belief(m, (0.40, 0.0, 0.0))
    result = planner.plan(belief, contact_seen=False, rng=np.random.default_rng(2))
    result = planner.plan(belief, contact_seen=True, rng=np.random.default_rng(3),
                          memory=result.memory)
    assert result.phase == "post-contact"
    result = planner.plan(belief, contact_seen=False, rng=np.random.default_rng(4),
                          memory=result.memory)
    assert result.phase == "post-contact"
    assert result.planning_ms >= 0


def test_thesis_planner_tracks_its_own_belief_with_the_executed_actions(small_hand_model,
                                                                        qmdp):
    """Without a search it acts on the discrete Bayes filter: the same actions as
    HandPolicy fed the same actions and readings."""
    from planning.hand.policy import HandPolicy

    m = small_hand_model
    belief = _belief(m, (0.15, 0.0, 0.0))
    planner = ThesisHandPlanner(m, qmdp, precontact=None)
    reference = HandPolicy(m, qmdp)
    reference.reset(belief, rng=np.random.default_rng(0))
    rng = np.random.default_rng(5)
    result = planner.plan(belief, contact_seen=False, rng=rng)
    assert result.action == reference.act() and result.phase == "post-contact"
    for reading in ([False, False], [True, False], [False, False]):
        reading = np.array(reading)
        reference.observe(result.action, reading, rng=rng)
        result = planner.plan(belief, contact_seen=False, rng=rng, memory=result.memory,
                              last_action=result.action, reading=reading)
        assert result.action == reference.act() and result.ranking[0] == result.action
    np.testing.assert_allclose(result.memory.discrete, reference.discrete)


def test_solve_settings_key_names_the_budget_not_its_spelling():
    assert HandSolveSettings(solve_seconds=60).key() == HandSolveSettings(
        solve_seconds=60.0).key()
    assert HandSolveSettings(seed=1).key() != HandSolveSettings(seed=2).key()
    with pytest.raises(ValueError):
        HandSolveSettings(solve_seconds=0)


def test_a_solved_problem_loads_back_from_the_cache(small_hand_solution):
    solution, settings, cache = small_hand_solution
    assert not solution.loaded_from_cache and set(solution.policies) == {"qmdp", "pomdp"}
    again = solve_hand_problem(settings, cache_dir=cache, progress=False)
    assert again.loaded_from_cache
    for name, policy in solution.policies.items():
        np.testing.assert_array_equal(again.policies[name].alphas, policy.alphas)
        np.testing.assert_array_equal(again.policies[name].alpha_actions,
                                      policy.alpha_actions)
    assert (again.model.pomdp.T[0] != solution.model.pomdp.T[0]).nnz == 0
    poses = np.array([[0.15, 0.02, 0.3], [0.5, 0.0, 0.0]])
    np.testing.assert_array_equal(again.model.index(poses), solution.model.index(poses))
