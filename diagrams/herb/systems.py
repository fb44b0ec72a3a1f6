"""LeafSystems of the closed-loop HERB diagram: where the hand and object are, the
hand-relative estimator, the controller and the action executor.

Each is an adapter over a pure core: :class:`estimation.hand.tracker.HandRelativeTracker`
(the filters), :class:`planning.hand.planner.HandPlanner` (any object with ``plan(belief,
*, contact_seen, rng) -> (action, stats)``) and :class:`models.herb.motion.HandMotionPlanner`
(the IK). Their timing:

- the estimator checks every ``check_period_s`` and updates once the palm has travelled
  ``travel_m`` (5 mm) since its last update (or on every check when ``travel_m`` is None);
- the controller checks every ``check_period_s`` and decides when the executor is idle
  (its last motion finished ``settle_s`` ago);
- the executor checks on the same period, half a period later, so it sees the decision
  made at the check before (Drake's discrete updates at one instant all read the state
  from before that instant).

Port layouts (world frame, SI): ``palm_pose`` and ``object_pose`` (3): x, y, theta;
``command`` (2): decision index, action index (-1: none); ``executor_state`` (11): the
commanded palm pose at the end of the current motion (3), the arm angles there (7), 1 when
idle else 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from estimation.hand.tracker import HandRelativeTracker
from estimation.particles.belief import ParticleBelief
from models.herb.kinematics import time_parameterize
from models.herb.motion import HandMotionPlanner
from models.herb.mount import NUM_ARM_JOINTS, planar_palm_pose
from models.herb.world import HerbWorld
from models.pose import transform_to_planar

EXECUTOR_STATE_SIZE = 3 + NUM_ARM_JOINTS + 1


class PlanarPoses(LeafSystem):
    """The palm's and the object's planar world poses from the plant's body poses.

    Input port: ``body_poses`` (the plant's, abstract).
    Output ports: ``palm_pose`` (3), ``object_pose`` (3), ``object_tilt`` (1): the angle
    (rad) between the object's vertical axis and the world's (a toppled object's planar
    pose means nothing).
    """

    def __init__(self, plant: MultibodyPlant, world: HerbWorld):
        super().__init__()
        palm = world.hand.palm_frame
        self._palm_body = int(palm.body().index())
        self._X_BP = palm.GetFixedPoseInBodyFrame()
        self._object_body = int(world.object_body.index())
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        self.DeclareVectorOutputPort("palm_pose", 3, self._palm)
        self.DeclareVectorOutputPort("object_pose", 3, self._object)
        self.DeclareVectorOutputPort("object_tilt", 1, self._tilt)

    def _palm(self, context, output: BasicVector) -> None:
        X_WB = self._poses.Eval(context)[self._palm_body]
        output.SetFromVector(planar_palm_pose(X_WB @ self._X_BP))

    def _object(self, context, output: BasicVector) -> None:
        output.SetFromVector(transform_to_planar(self._poses.Eval(context)[self._object_body]))

    def _tilt(self, context, output: BasicVector) -> None:
        z = self._poses.Eval(context)[self._object_body].rotation().col(2)
        output.SetFromVector([np.arccos(np.clip(z[2], -1.0, 1.0))])


class _Handle:
    """A mutable core held in abstract state. Drake copies abstract state at every
    unrestricted update; copies of a started handle share its core (the filters and the
    planner are costly to copy and stateful), while an unstarted one copies to a fresh
    handle, so every new context starts its own core."""

    def __init__(self):
        self.core = None
        self.log: list = []

    def __deepcopy__(self, memo):
        return self if self.core is not None else _Handle()


class HandEstimator(LeafSystem):
    """The object's pose relative to the hand, as a particle belief.

    Input ports: ``sensor_contact`` (S) binary readings, ``palm_pose`` (3) measured.
    Output ports: ``belief`` (abstract :class:`ParticleBelief`, hand frame), ``mean`` (3,
    hand frame), ``contact_seen`` (1).

    Args:
        make_filter: builds the filter (CPF or MPF) for a new episode.
        initial: the initial belief (hand frame).
        seed: update ``k`` draws from ``default_rng([seed, k])``.
        travel_m: palm travel between updates (m); ``None``: update on every check.
        check_period_s: how often to check (s).
    """

    def __init__(self, make_filter, initial: ParticleBelief, sensor_count: int, *,
                 seed: int = 0, travel_m: float | None = 0.005,
                 check_period_s: float = 0.01):
        super().__init__()
        self._make_filter = make_filter
        self._initial = initial
        self._seed = seed
        self._travel = travel_m
        self._readings = self.DeclareVectorInputPort("sensor_contact", sensor_count)
        self._palm = self.DeclareVectorInputPort("palm_pose", 3)
        self._handle = self.DeclareAbstractState(AbstractValue.Make(_Handle()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(check_period_s, 0.0, self._update)
        self.DeclareAbstractOutputPort("belief", lambda: AbstractValue.Make(initial),
                                       self._output_belief,
                                       prerequisites_of_calc={self.all_state_ticket()})
        self.DeclareVectorOutputPort("mean", 3, self._output_mean,
                                     prerequisites_of_calc={self.all_state_ticket()})
        self.DeclareVectorOutputPort("contact_seen", 1, self._output_contact,
                                     prerequisites_of_calc={self.all_state_ticket()})

    def tracker(self, context) -> HandRelativeTracker | None:
        """The tracker inside ``context`` (``None`` before the first check)."""
        return context.get_abstract_state(int(self._handle)).get_value().core

    def _update(self, context, state) -> EventStatus:
        handle = state.get_mutable_abstract_state(int(self._handle)).get_value()
        palm = self._palm.Eval(context)
        if handle.core is None:
            handle.core = HandRelativeTracker(self._make_filter(), self._initial, palm)
            return EventStatus.Succeeded()
        tracker: HandRelativeTracker = handle.core
        moved = float(np.linalg.norm(palm[:2] - tracker.hand_pose_W[:2]))
        if self._travel is not None and moved < self._travel:
            return EventStatus.DidNothing()
        reading = self._readings.Eval(context) > 0.5
        diagnostics = tracker.update(palm, reading,
                                     rng=np.random.default_rng([self._seed, tracker.updates]))
        handle.log.append((context.get_time(), palm.copy(), reading.copy(), diagnostics))
        return EventStatus.Succeeded()

    def _belief(self, context) -> ParticleBelief:
        tracker = self.tracker(context)
        return self._initial if tracker is None else tracker.belief

    def _output_belief(self, context, output) -> None:
        output.set_value(self._belief(context))

    def _output_mean(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._belief(context).mean())

    def _output_contact(self, context, output: BasicVector) -> None:
        tracker = self.tracker(context)
        output.SetFromVector([float(tracker is not None and tracker.contact_seen)])


@dataclass
class Decision:
    """One decision of the controller (what a summary reports per step).

    Attributes:
        time_s: simulation time of the decision.
        action: the action sent (-1: none, the episode ends).
        phase: ``pre-contact`` or ``post-contact``.
        planning_ms: the planner's wall time.
        rejected: actions the planner preferred that were infeasible, with the reason.
        palm_pose: (3,) the commanded palm pose the action starts from.
        belief: the belief the planner was given (hand frame).
    """

    time_s: float
    action: int
    phase: str
    planning_ms: float
    rejected: list[tuple[int, str]] = field(default_factory=list)
    palm_pose: np.ndarray | None = None
    belief: ParticleBelief | None = None


class HandController(LeafSystem):
    """Asks the planner for an action whenever the executor is idle, and sends the best
    one whose motion is feasible.

    Input ports: ``belief`` (abstract), ``contact_seen`` (1), ``executor_state`` (11),
    ``sensor_contact`` (S): the reading handed to the planner with the last action.
    Output port: ``command`` (2).

    Args:
        make_planner: builds the planner for a new episode.
        motion: the IK of actions (shared with the executor).
        action_vectors: (A, 3) hand-frame displacement of each action (m, m, rad).
        horizon: decisions per episode; after it the command is -1.
        on_infeasible: ``"next"``: fall back to the planner's next-ranked feasible action;
            ``"stop"``: end the episode when the preferred action is infeasible (the
            thesis' real-robot trials, sec. 6.5). Infeasible actions are never sent.
        seed: decision ``k`` draws from ``default_rng([seed, k])``.
        check_period_s: how often to check (s).
    """

    def __init__(self, make_planner, motion: HandMotionPlanner, action_vectors: np.ndarray,
                 initial: ParticleBelief, sensor_count: int, *, horizon: int,
                 on_infeasible: str = "stop", seed: int = 0, check_period_s: float = 0.02):
        super().__init__()
        if on_infeasible not in ("next", "stop"):
            raise ValueError(f"on_infeasible must be 'next' or 'stop', got {on_infeasible!r}")
        self._make_planner = make_planner
        self._motion = motion
        self._actions = np.asarray(action_vectors, dtype=float)
        self._horizon = horizon
        self._on_infeasible = on_infeasible
        self._seed = seed
        self._belief = self.DeclareAbstractInputPort("belief", AbstractValue.Make(initial))
        self._contact = self.DeclareVectorInputPort("contact_seen", 1)
        self._executor = self.DeclareVectorInputPort("executor_state", EXECUTOR_STATE_SIZE)
        self._readings = self.DeclareVectorInputPort("sensor_contact", sensor_count)
        self._handle = self.DeclareAbstractState(AbstractValue.Make(_Handle()))
        self._command = self.DeclareDiscreteState(np.array([0.0, -1.0]))
        self.DeclarePeriodicUnrestrictedUpdateEvent(check_period_s, 0.0, self._update)
        self.DeclareStateOutputPort("command", self._command)

    def decisions(self, context) -> list[Decision]:
        return context.get_abstract_state(int(self._handle)).get_value().log

    def finished(self, context) -> bool:
        """Has the controller stopped (horizon reached or no feasible action)?"""
        log = self.decisions(context)
        return bool(log) and (log[-1].action < 0 or len(log) >= self._horizon)

    def _update(self, context, state) -> EventStatus:
        executor = self._executor.Eval(context)
        if executor[-1] < 0.5 or self.finished(context):
            return EventStatus.DidNothing()
        handle = state.get_mutable_abstract_state(int(self._handle)).get_value()
        if handle.core is None:
            handle.core = self._make_planner()
        k = len(handle.log)
        belief = self._belief.Eval(context)
        last = handle.log[-1].action if handle.log else -1
        _, stats = handle.core.plan(belief,
                                    contact_seen=bool(self._contact.Eval(context)[0] > 0.5),
                                    rng=np.random.default_rng([self._seed, k]),
                                    last_action=last if last >= 0 else None,
                                    reading=self._readings.Eval(context) > 0.5)
        pose, q = executor[:3], executor[3:3 + NUM_ARM_JOINTS]
        chosen, rejected = -1, []
        for a in stats["ranking"]:
            path = self._motion.plan(pose, q, self._actions[a])
            if path.feasible:
                chosen = a
                break
            rejected.append((a, path.reason))
            if self._on_infeasible == "stop":
                break
        handle.log.append(Decision(context.get_time(), chosen, stats["phase"],
                                   stats["planning_ms"], rejected, pose.copy(), belief))
        state.get_mutable_discrete_state(int(self._command)).SetFromVector([k + 1, chosen])
        return EventStatus.Succeeded()


class _Motion:
    """The executor's current motion: the joint trajectory, where it ends, the decision it
    executes, and how many infeasible commands the executor has refused so far."""

    def __init__(self, trajectory: PiecewisePolynomial, pose: np.ndarray, q: np.ndarray,
                 decision: int, refused: int = 0):
        self.trajectory, self.pose, self.q = trajectory, pose, q
        self.decision, self.refused = decision, refused


class ActionExecutor(LeafSystem):
    """Turns each commanded action into an arm motion: the joint path from
    :class:`HandMotionPlanner`, timed at ``hand_speed_m_per_s`` within the joints' velocity
    limits, tracked by the plant's joint PD controllers.

    A command whose motion is infeasible is refused (counted in ``refused``; the arm holds
    still): the controller is meant never to send one.

    Input port: ``command`` (2).
    Output ports: ``arm_desired_state`` (14: positions, velocities), ``executor_state``
    (11; see the module docstring).

    Args:
        motion: the IK of actions (shared with the controller).
        action_vectors: (A, 3) hand-frame displacement of each action.
        start_pose: (3,) the palm's planar world pose at the start; start_q: (7,) the arm
            angles there.
        hand_speed_m_per_s: nominal palm speed.
        settle_s: still time after a motion before the executor reports idle.
        check_period_s: how often to check (s); offset by half a period.
    """

    def __init__(self, motion: HandMotionPlanner, action_vectors: np.ndarray,
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
        initial = _Motion(hold, np.asarray(start_pose, dtype=float), np.asarray(start_q), 0)
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

    def motion(self, context) -> _Motion:
        return context.get_abstract_state(int(self._state)).get_value()

    def _update(self, context, state) -> EventStatus:
        decision, action = self._command.Eval(context)
        current = self.motion(context)
        if int(decision) <= current.decision or action < 0:
            return EventStatus.DidNothing()
        path = self._motion_planner.plan(current.pose, current.q, self._actions[int(action)])
        if not path.feasible:  # refused, never executed: the arm holds still
            state.get_mutable_abstract_state(int(self._state)).set_value(_Motion(
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
            _Motion(trajectory, path.poses[-1].copy(), path.q[-1].copy(), int(decision),
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
