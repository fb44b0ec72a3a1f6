"""The closed loop's action executor: each commanded action becomes a timed arm motion.

Port layouts (world frame, SI): ``command`` (2): decision index, action index (-1: none);
``executor_state`` (11): the commanded palm pose at the end of the current motion (3), the
arm angles there (7), 1 when idle else 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from models.herb.kinematics import time_parameterize
from models.herb.motion import MotionPlanner
from models.herb.mount import NUM_ARM_JOINTS

EXECUTOR_STATE_SIZE = 3 + NUM_ARM_JOINTS + 1


@dataclass(frozen=True)
class Motion:
    """The executor's Context state: the current motion's joint trajectory, the palm pose
    (3,) and arm angles (7,) where it ends, the decision it executes, and how many
    infeasible commands the executor has refused so far."""

    trajectory: PiecewisePolynomial
    pose: np.ndarray
    q: np.ndarray
    decision: int
    refused: int = 0

    def __deepcopy__(self, memo) -> Motion:
        return self  # immutable: a copy would be the same value


class ActionExecutor(LeafSystem):
    """Turns each commanded action into an arm motion: the joint path from the motion
    planner (IK, or the lattice's edge), timed at ``hand_speed_m_per_s`` within the joints' velocity
    limits, tracked by the plant's joint PD controllers.

    A command whose motion is infeasible is refused (counted in ``refused``; the arm holds
    still): the controller is meant never to send one. The current :class:`Motion` is the
    Context state; the motion planner (over a kinematic copy of the robot) is a
    member, shared with the controller.

    Input port: ``command`` (2).
    Output ports: ``arm_desired_state`` (14: positions rad, velocities rad/s),
    ``executor_state`` (11; see the module docstring).

    Args:
        motion: the joint paths of actions (shared with the controller).
        action_vectors: (A, 3) hand-frame displacement of each action (m, m, rad).
        start_pose: (3,) the palm's planar world pose at the start; start_q: (7,) the arm
            angles there.
        hand_speed_m_per_s: nominal palm speed.
        settle_s: still time after a motion before the executor reports idle.
        check_period_s: how often to check (s); offset by half a period, so it sees the
            decision the controller made at the check before (Drake's discrete updates at
            one instant all read the state from before that instant).
    """

    def __init__(self, motion: MotionPlanner, action_vectors: np.ndarray,
                 start_pose: np.ndarray, start_q: np.ndarray, *,
                 hand_speed_m_per_s: float = 0.05, settle_s: float = 0.2,
                 check_period_s: float = 0.02):
        super().__init__()
        self._motion_planner = motion
        self._actions = np.asarray(action_vectors, dtype=float)
        self._speed = hand_speed_m_per_s
        self._settle = settle_s
        hold = PiecewisePolynomial.ZeroOrderHold([0.0, settle_s],
                                                 np.column_stack([start_q, start_q]))
        initial = Motion(hold, np.asarray(start_pose, dtype=float), np.asarray(start_q), 0)
        self._command = self.DeclareVectorInputPort("command", 2)
        self._state = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclarePeriodicUnrestrictedUpdateEvent(check_period_s, check_period_s / 2,
                                                    self._update)
        self.DeclareVectorOutputPort("arm_desired_state", 2 * NUM_ARM_JOINTS, self._desired,
                                     prerequisites_of_calc={self.all_state_ticket(),
                                                            self.time_ticket()})
        self.DeclareVectorOutputPort("executor_state", EXECUTOR_STATE_SIZE, self._status,
                                     prerequisites_of_calc={self.all_state_ticket(),
                                                            self.time_ticket()})

    def motion(self, context) -> Motion:
        return context.get_abstract_state(int(self._state)).get_value()

    def _update(self, context, state) -> EventStatus:
        decision, action = self._command.Eval(context)
        current = self.motion(context)
        if int(decision) <= current.decision or action < 0:
            return EventStatus.DidNothing()
        path = self._motion_planner.plan(current.pose, current.q, self._actions[int(action)])
        if not path.feasible:  # refused, never executed: the arm holds still
            state.get_mutable_abstract_state(int(self._state)).set_value(Motion(
                current.trajectory, current.pose, current.q, int(decision),
                current.refused + 1))
            return EventStatus.Succeeded()
        t0 = context.get_time()
        times = t0 + time_parameterize(path.q, path.poses, hand_speed_m_per_s=self._speed,
                                       velocity_limits=self._motion_planner.ik.velocity_limits)
        zeros = np.zeros(NUM_ARM_JOINTS)
        trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            times, path.q.T, zeros, zeros)
        state.get_mutable_abstract_state(int(self._state)).set_value(
            Motion(trajectory, path.poses[-1].copy(), path.q[-1].copy(), int(decision),
                   current.refused))
        return EventStatus.Succeeded()

    def _desired(self, context, output: BasicVector) -> None:
        trajectory = self.motion(context).trajectory
        t = min(max(context.get_time(), trajectory.start_time()), trajectory.end_time())
        q = trajectory.value(t).ravel()
        v = trajectory.EvalDerivative(t, 1).ravel()
        output.SetFromVector(np.concatenate([q, v]))

    def _status(self, context, output: BasicVector) -> None:
        m = self.motion(context)
        idle = context.get_time() >= m.trajectory.end_time() + self._settle
        output.SetFromVector(np.concatenate([m.pose, m.q, [float(idle)]]))
