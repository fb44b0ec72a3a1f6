"""The closed loop's systems over the lattice: the controller falls back along the
planner's ranking to a feasible lattice edge, the executor runs that edge's joint path, and
the lattice motion planner refuses what is off the lattice."""

import numpy as np
from pydrake.systems.analysis import Simulator

from diagrams.herb.controller import HandController
from diagrams.herb.executor import EXECUTOR_STATE_SIZE, ActionExecutor
from estimation.particles.belief import ParticleBelief
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.motion import LatticeMotion
from planning.protocols import PlanResult

FORWARD, BACK, LEFT, RIGHT = range(4)


class RankingPlanner:
    """Always the same ranking; records the palm pose it was given."""

    def __init__(self, ranking):
        self.ranking = tuple(ranking)
        self.palm_poses = []

    def plan(self, belief, *, rng, palm_pose, **context):
        self.palm_poses.append(palm_pose)
        return PlanResult(self.ranking[0], self.ranking, "lat-despot", 1.0)


def _belief():
    rng = np.random.default_rng(0)
    return ParticleBelief.uniform(np.column_stack([rng.uniform(0.15, 0.17, 50),
                                                   rng.uniform(-0.02, 0.02, 50),
                                                   np.zeros(50)]))


def test_lattice_motion_runs_the_edge_and_refuses_what_is_off_the_lattice(
        wall, small_table, moves):
    lattice = ConfigurationLattice(wall, small_table, moves)
    motion = LatticeMotion(lattice)
    start = lattice.start_point
    pose, q = lattice.poses[start], small_table.q[start]
    back = motion.plan(pose, q, moves[BACK])
    assert back.feasible
    np.testing.assert_array_equal(back.q, lattice.edge(start, BACK).q)
    assert not motion.plan(pose, q, moves[RIGHT]).feasible  # the wall
    assert "lattice point" in motion.plan(pose + [0.005, 0, 0], q, moves[BACK]).reason
    assert "templates" in motion.plan(pose, q, np.array([0.01, 0, 0])).reason
    assert "configuration" in motion.plan(pose, q + 0.1, moves[BACK]).reason


def test_controller_and_executor_take_the_next_feasible_lattice_edge(wall, small_table,
                                                                      moves):
    lattice = ConfigurationLattice(wall, small_table, moves)
    motion = LatticeMotion(lattice)
    start = lattice.start_point
    planner = RankingPlanner([RIGHT, BACK, FORWARD, LEFT])
    controller = HandController(planner, motion, moves, _belief(), 2, horizon=3,
                                on_infeasible="next")
    context = controller.CreateDefaultContext()
    controller.GetInputPort("belief").FixValue(context, _belief())
    controller.GetInputPort("contact_seen").FixValue(context, [0.0])
    controller.GetInputPort("sensor_contact").FixValue(context, [0.0, 0.0])
    state = np.concatenate([lattice.poses[start], small_table.q[start], [1.0]])
    controller.GetInputPort("executor_state").FixValue(context, state)
    Simulator(controller, context).AdvanceTo(0.0)
    decision = controller.decisions(context)[0]
    assert decision.action == BACK and decision.rejected[0][0] == RIGHT
    assert "wall" in decision.rejected[0][1]
    np.testing.assert_allclose(planner.palm_poses[0], lattice.poses[start])

    executor = ActionExecutor(motion, moves, lattice.poses[start], small_table.q[start],
                              hand_speed_m_per_s=0.05, settle_s=0.1)
    ex_context = executor.CreateDefaultContext()
    executor.GetInputPort("command").FixValue(ex_context, [1.0, BACK])
    simulator = Simulator(executor, ex_context)
    simulator.AdvanceTo(2.0)
    target = lattice.neighbours[start, BACK]
    out = executor.GetOutputPort("executor_state").Eval(ex_context)
    assert len(out) == EXECUTOR_STATE_SIZE and out[-1] == 1.0  # idle again
    np.testing.assert_allclose(out[:2], lattice.poses[target, :2], atol=2e-4)
    np.testing.assert_allclose(out[3:10], small_table.q[target])
    desired = executor.GetOutputPort("arm_desired_state").Eval(ex_context)
    np.testing.assert_allclose(desired[:7], small_table.q[target], atol=1e-9)
