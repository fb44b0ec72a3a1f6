"""The closed loop's controller: a LeafSystem that asks a planner
(:class:`planning.protocols.Planner`) for an action whenever the executor is idle and sends
the best one whose arm motion is feasible."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem

from diagrams.herb.executor import EXECUTOR_STATE_SIZE
from estimation.particles.belief import ParticleBelief
from models.herb.motion import MotionPlanner
from models.herb.mount import NUM_ARM_JOINTS
from planning.protocols import Planner


@dataclass(frozen=True)
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
    rejected: tuple[tuple[int, str], ...] = ()
    palm_pose: np.ndarray | None = None
    belief: ParticleBelief | None = None


@dataclass(frozen=True)
class ControllerState:
    """The controller's Context state: the decisions so far and the planner's memory (the
    last :attr:`~planning.protocols.PlanResult.memory`)."""

    decisions: tuple[Decision, ...] = ()
    memory: Any = None

    def __deepcopy__(self, memo) -> ControllerState:
        return self  # immutable: a copy would be the same value


class HandController(LeafSystem):
    """Asks the planner for an action whenever the executor is idle, and sends the best
    one whose motion is feasible.

    The decisions and the planner's memory live in the Context (:class:`ControllerState`);
    the planner and the motion planner (immutable cores: a solved policy, Drake IK) are
    members shared by every Context. It checks every ``check_period_s`` and decides when
    the executor is idle (its last motion finished ``settle_s`` ago).

    Input ports: ``belief`` (abstract), ``contact_seen`` (1), ``executor_state`` (11),
    ``sensor_contact`` (S): the reading handed to the planner with the last action.
    Output port: ``command`` (2): decision index, action index (-1: none).

    Args:
        planner: answers ``plan(belief, *, rng, memory, contact_seen, last_action,
            reading, palm_pose) -> PlanResult`` (``palm_pose``: the commanded palm pose the
            action starts from, world frame).
        motion: the joint paths of actions (IK, or the lattice's edges; shared with the
            executor).
        action_vectors: (A, 3) hand-frame displacement of each action (m, m, rad).
        initial: the initial belief (for the input port's model value).
        sensor_count: S.
        horizon: decisions per episode; after it the command is -1.
        on_infeasible: ``"next"``: fall back to the planner's next-ranked feasible action;
            ``"stop"``: end the episode when the preferred action is infeasible (the
            thesis' real-robot trials, sec. 6.5). Infeasible actions are never sent.
        seed: decision ``k`` draws from ``default_rng([seed, k])``.
        check_period_s: how often to check (s).
    """

    def __init__(self, planner: Planner, motion: MotionPlanner, action_vectors: np.ndarray,
                 initial: ParticleBelief, sensor_count: int, *, horizon: int,
                 on_infeasible: str = "stop", seed: int = 0, check_period_s: float = 0.02):
        super().__init__()
        if on_infeasible not in ("next", "stop"):
            raise ValueError(f"on_infeasible must be 'next' or 'stop', got {on_infeasible!r}")
        self._planner = planner
        self._motion = motion
        self._actions = np.asarray(action_vectors, dtype=float)
        self._horizon = horizon
        self._on_infeasible = on_infeasible
        self._seed = seed
        self._belief = self.DeclareAbstractInputPort("belief", AbstractValue.Make(initial))
        self._contact = self.DeclareVectorInputPort("contact_seen", 1)
        self._executor = self.DeclareVectorInputPort("executor_state", EXECUTOR_STATE_SIZE)
        self._readings = self.DeclareVectorInputPort("sensor_contact", sensor_count)
        self._state = self.DeclareAbstractState(AbstractValue.Make(ControllerState()))
        self._command = self.DeclareDiscreteState(np.array([0.0, -1.0]))
        self.DeclarePeriodicUnrestrictedUpdateEvent(check_period_s, 0.0, self._update)
        self.DeclareStateOutputPort("command", self._command)

    def decisions(self, context) -> tuple[Decision, ...]:
        return context.get_abstract_state(int(self._state)).get_value().decisions

    def finished(self, context) -> bool:
        """Has the controller stopped (horizon reached or no feasible action)?"""
        log = self.decisions(context)
        return bool(log) and (log[-1].action < 0 or len(log) >= self._horizon)

    def _update(self, context, state) -> EventStatus:
        executor = self._executor.Eval(context)
        if executor[-1] < 0.5 or self.finished(context):
            return EventStatus.DidNothing()
        previous: ControllerState = context.get_abstract_state(int(self._state)).get_value()
        k = len(previous.decisions)
        belief = self._belief.Eval(context)
        last = previous.decisions[-1].action if previous.decisions else -1
        pose, q = executor[:3], executor[3:3 + NUM_ARM_JOINTS]
        result = self._planner.plan(belief, rng=np.random.default_rng([self._seed, k]),
                                    memory=previous.memory,
                                    contact_seen=bool(self._contact.Eval(context)[0] > 0.5),
                                    last_action=last if last >= 0 else None,
                                    reading=self._readings.Eval(context) > 0.5,
                                    palm_pose=pose.copy())
        chosen, rejected = -1, []
        for a in result.ranking:
            path = self._motion.plan(pose, q, self._actions[a])
            if path.feasible:
                chosen = a
                break
            rejected.append((a, path.reason))
            if self._on_infeasible == "stop":
                break
        decision = Decision(context.get_time(), chosen, result.phase, result.planning_ms,
                            tuple(rejected), pose.copy(), belief)
        state.get_mutable_abstract_state(int(self._state)).set_value(
            ControllerState((*previous.decisions, decision), result.memory))
        state.get_mutable_discrete_state(int(self._command)).SetFromVector([k + 1, chosen])
        return EventStatus.Succeeded()
