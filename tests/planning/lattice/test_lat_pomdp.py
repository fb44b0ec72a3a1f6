"""Lat-POMDP: transitions into s_bad, the compiled Lift rollout, and Theorem 7.1."""

import numpy as np
import pytest

from models.planar.world import PlanarWorld
from planning.hand.beliefs import GaussianBelief
from planning.hand.discretization import HandProblemSpec
from planning.hand.model import build_hand_pomdp
from planning.hand.policy import qmdp_vectors
from planning.lattice.contact import UnmodelledContact
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.planners import LatDespotPlanner, LiftPolicy
from planning.lattice.pomdp import BAD, LatticePOMDP
from planning.pomdp.despot import DespotSettings
from planning.pomdp.qmdp import solve_mdp

FORWARD, BACK, LEFT, RIGHT = range(4)


@pytest.fixture(scope="module")
def hand_model(small_problem):
    world = PlanarWorld.load("bottle", sensors="fingertips", error_rate=0.0)
    return build_hand_pomdp(world, HandProblemSpec.load(small_problem),
                            rng=np.random.default_rng(0), progress=False)


@pytest.fixture(scope="module")
def ahead():
    """The bottle 16 cm ahead of the palm, uncertain sideways (the ch. 7 belief)."""
    return GaussianBelief((0.16, 0.0, 0.0), (0.005, 0.03, np.pi))


@pytest.fixture(scope="module")
def lat(hand_model, wall, small_table, ahead):
    lattice = ConfigurationLattice(wall, small_table, hand_model.spec.action_vectors())
    return LatticePOMDP(hand_model, lattice, UnmodelledContact(wall), inner="discrete",
                        initial=ahead)


def test_an_infeasible_action_ends_in_s_bad_with_its_whole_future(lat):
    rows = lat.sample_initial(6, rng=np.random.default_rng(1))
    u = np.random.default_rng(2).random((6, lat.uniforms_per_step))
    step = lat.step(rows, RIGHT, u)  # the wall
    assert (step.next_states[:, 0] == BAD).all() and step.terminal.all()
    np.testing.assert_allclose(step.rewards, -1 / (1 - lat.discount))
    back = lat.step(rows, BACK, u)
    assert (back.next_states[:, 0] == lat.lattice.neighbours[lat.lattice.start_point,
                                                             BACK]).all()
    assert not back.terminal.any() and (back.rewards > -1.0 - 1e-12).all()
    assert (lat.upper_bound(step.next_states) == 0).all()


def test_an_object_pushed_into_an_obstacle_is_unmodelled_contact(wall):
    contact = UnmodelledContact(wall)
    palm = np.tile(wall.hand_start.as_array(), (3, 1))
    wall_y = wall.obstacles[0].pose.y - wall.hand_start.y  # hand frame: to the right
    poses = np.array([[0.05, wall_y + 0.05, 0.0], [0.16, wall_y + 0.05, 0.0],
                      [5.0, 0.0, 0.0]])
    # touching the wall's side (4 cm thick, bottle radius 3.6 cm); past its end; off
    # the table
    assert contact.touches(palm, poses).tolist() == [True, False, True]


def test_the_compiled_rollout_equals_stepping_the_lifted_policy(lat):
    rng = np.random.default_rng(3)
    rows = np.vstack([lat.sample_initial(5, rng=rng), lat.sample_initial(4, rng=rng)])
    rows[5:, 0] = lat.lattice.neighbours[lat.lattice.start_point, BACK]
    offsets, depth = np.array([0, 5, 9]), 12
    uniforms = rng.random((9, depth + 1, lat.uniforms_per_step))
    scenarios = np.arange(9)
    compiled = lat.rollout(rows, scenarios, np.zeros(9, dtype=np.int64), offsets, uniforms,
                           depth)
    expected = np.zeros(9)
    for lo, hi in zip(offsets[:-1], offsets[1:], strict=True):
        states, scale = rows[lo:hi].copy(), np.ones(hi - lo)
        alive = np.ones(hi - lo, dtype=bool)
        for t in range(depth):
            if not alive.any():
                break
            a = lat.default_actions(states[alive])[0]
            step = lat.step(states[alive], a, uniforms[scenarios[lo:hi][alive], t])
            idx = np.flatnonzero(alive)
            expected[lo + idx] += scale[idx] * step.rewards
            states[idx] = step.next_states
            scale[idx] *= lat.discount
            alive[idx] = ~step.terminal
    np.testing.assert_allclose(compiled, expected, atol=1e-12)


@pytest.mark.parametrize("rollout", ["qmdp", "vectors"])
def test_the_compiled_lat_despot_is_the_python_search(hand_model, wall, small_table, ahead,
                                                       rollout):
    """The compiled engine on the discrete Lat-POMDP (kernels that stop to have the lattice
    evaluated, then run the trial again) builds the Python engine's tree, and evaluates
    the same edges, each of them asked for; on fresh lattices, with Lift-QMDP rollouts and
    with a hand-relative policy's vectors (as Lat-DESPOT-PB's)."""
    from planning.pomdp.despot import Despot

    q = solve_mdp(hand_model.pomdp)
    vectors = None if rollout == "qmdp" else qmdp_vectors(q + 0.5 * np.roll(q, 1, axis=1),
                                                          hand_model.pomdp.actions)
    rng = np.random.default_rng(6)
    poses = GaussianBelief((0.16, -0.03, 0.0), (0.005, 0.02, np.pi)).sample(
        hand_model.world, 300, rng=rng)
    results = []
    for engine in ("python", "compiled"):
        lattice = ConfigurationLattice(wall, small_table, hand_model.spec.action_vectors())
        model = LatticePOMDP(hand_model, lattice, UnmodelledContact(wall), initial=ahead,
                             rollout_policy=vectors)
        assert lattice.stats().edges_evaluated == 0  # building the planner evaluated nothing
        search = Despot(model, DespotSettings(scenarios=40, depth=30, max_trials=25,
                                              seconds=60, engine=engine))
        rows = model.from_poses(lattice.start_point, poses)
        action, stats, _ = search.search(rows, rng=np.random.default_rng(7))
        results.append((action, stats, lattice.status.copy(), lattice.asked.copy()))
    (a, python, status_p, asked_p), (b, compiled, status_c, asked_c) = results
    assert a == b and python.nodes == compiled.nodes and python.trials == compiled.trials
    np.testing.assert_allclose(compiled.action_lower, python.action_lower, atol=1e-9)
    np.testing.assert_allclose(compiled.action_upper, python.action_upper, atol=1e-9)
    np.testing.assert_array_equal(status_c, status_p)
    assert (status_c != -1).sum() > 4 and np.all(asked_c[status_c != -1])
    np.testing.assert_array_equal(asked_c, asked_p)


def test_lift_qmdp_replaces_the_infeasible_choice(lat, hand_model):
    q = qmdp_vectors(solve_mdp(hand_model.pomdp), hand_model.pomdp.actions)
    right = GaussianBelief((0.16, -0.05, 0.0), (0.005, 0.005, np.pi))
    belief = hand_model.belief(right.sample(hand_model.world, 500,
                                            rng=np.random.default_rng(4)))
    assert q.act(belief) == RIGHT  # Rel-QMDP moves right, into the wall
    lift = LiftPolicy(q, lat.lattice)
    result = lift.plan(belief, rng=np.random.default_rng(0),
                       palm_pose=lat.lattice.poses[lat.lattice.start_point])
    assert result.action != RIGHT and result.ranking[-1] == RIGHT


def test_theorem_7_1_lat_despot_never_chooses_an_infeasible_action(lat, ahead):
    """With V > -1/(1 - gamma) at the root, DESPOT's choice is feasible: from the start,
    where moving right hits the wall, over beliefs that draw the hand right."""
    planner = LatDespotPlanner(lat, DespotSettings(scenarios=30, depth=30, max_trials=20,
                                                   seconds=10.0))
    start = lat.lattice.start_point
    floor = -1 / (1 - lat.discount)
    for seed in range(4):
        rng = np.random.default_rng(seed)
        mean = (0.16, rng.uniform(-0.05, -0.02), 0.0)
        poses = GaussianBelief(mean, (0.005, 0.02, np.pi)).sample(lat.model.world, 200,
                                                                  rng=rng)
        result = planner.plan(lat.model.index(poses)[:, None], rng=rng, point=start)
        assert result.stats["lower"] > floor
        assert lat.lattice.feasible([start], [result.action])[0]
        assert result.ranking[-1] == RIGHT  # infeasible: ranked last


def test_lat_despot_plans_on_the_continuous_model_from_pose_particles(lat, ahead):
    """The estimator's particles as they are (poses), on the planar pushing model: the
    same bounds, and still never the infeasible move."""
    from estimation.particles.belief import ParticleBelief

    continuous = LatticePOMDP(lat.model, lat.lattice, lat.contact, inner="continuous")
    planner = LatDespotPlanner(continuous, DespotSettings(scenarios=20, depth=20,
                                                          max_trials=5, seconds=10.0))
    rng = np.random.default_rng(5)
    poses = GaussianBelief((0.16, -0.04, 0.0), (0.005, 0.01, np.pi)).sample(
        lat.model.world, 100, rng=rng)
    start = lat.lattice.start_point
    result = planner.plan(ParticleBelief.uniform(poses), rng=rng,
                          palm_pose=lat.lattice.poses[start])
    assert result.stats["trials"] == 5 and result.action != RIGHT
    rows = continuous.from_poses(start, poses[:3])
    np.testing.assert_array_equal(rows[:, 1:], poses[:3])  # poses, not cells


def test_outside_the_trust_region_return_charges_the_steps_back(lat):
    """``outside="return"``: a pose 5 cm left of the region (3 steps of 2 cm) is valued as
    three steps of -1 and then the nearest cell's bound; the sentinel values it as lost."""
    sentinel = LatticePOMDP(lat.model, lat.lattice, lat.contact, inner="continuous")
    back = LatticePOMDP(lat.model, lat.lattice, lat.contact, inner="continuous",
                        outside="return")
    start = lat.lattice.start_point
    rows = back.from_poses(start, np.array([[0.15, 0.11, 0.3], [0.15, -0.03, 0.3]]))
    cells, steps = back.bound_cells(rows)
    np.testing.assert_array_equal(steps, [3, 0])
    nearest = lat.model.index(np.array([[0.15, 0.05, 0.3]]))[0]
    assert cells[0] == nearest and cells[1] == sentinel.cells(rows)[1]
    gamma, v = lat.discount, lat.tabular.q_values.max(axis=1)
    np.testing.assert_allclose(back.upper_bound(rows),
                               [gamma ** 3 * v[nearest] - (1 - gamma ** 3) / (1 - gamma),
                                v[cells[1]]])
    lost = -1 / (1 - gamma)
    np.testing.assert_allclose(sentinel.upper_bound(rows)[0], lost)
    np.testing.assert_allclose(sentinel.upper_bound(rows)[1], back.upper_bound(rows)[1])
    u = np.random.default_rng(3).random((1, 21, lat.uniforms_per_step))
    args = (np.zeros(1, dtype=np.int64), np.zeros(1, dtype=np.int64), np.array([0, 1]), u, 20)
    twenty_lost = -(1 - gamma ** 20) / (1 - gamma)  # the sentinel's -1 a step, 20 deep
    np.testing.assert_allclose(sentinel.rollout(rows[:1], *args), twenty_lost)
    assert back.rollout(rows[:1], *args)[0] > twenty_lost + 1.0
    with pytest.raises(ValueError, match="continuous"):
        LatticePOMDP(lat.model, lat.lattice, lat.contact, outside="return")
