"""The closed loop's planner: the pre-contact trajectory, then the post-contact policy,
acting on the estimator's particle belief (DESIGN.md's planner seam).

:class:`~planning.hand.policy.HandPolicy` is the thesis' execution (sec. 6.1, 6.4.1): it
keeps its own beliefs (a particle filter before contact, the discrete Bayes filter of the
planning model after). In the closed-loop diagram the belief comes from the estimator
system instead (the MPF by default), so :class:`HandPlanner` is stateless about beliefs:

- before contact it returns the next action of the weighted A* trajectory
  (:class:`~planning.hand.precontact.PreContactPlanner`), searched once from the first belief it
  is given;
- from the first decision after the estimator has seen contact, or once the trajectory is
  used up, it discretises the particle belief onto the model's states
  (:meth:`~planning.hand.model.HandPOMDP.belief`) and acts with the post-contact vectors
  (QMDP's Q columns or the point-based policy's alpha-vectors).

Every answer ranks all actions, so a controller that finds the best one infeasible can fall
back to the next: by the post-contact vectors' value at the current belief.

:class:`ThesisHandPlanner` is the faithful alternative with the same interface: it runs
:class:`~planning.hand.policy.HandPolicy` on its own beliefs, started from the first
belief it is given and updated with the action executed and the reading at each decision,
so the post-contact belief update is the planning model's own (sec. 6.4.1).

Both answer the :class:`~planning.protocols.Planner` protocol and are immutable: what they
remember between decisions is the :attr:`~planning.protocols.PlanResult.memory` of their
last answer.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from estimation.particles.belief import ParticleBelief
from planning.hand.model import HandPOMDP
from planning.hand.policy import HandPolicy, HandPolicyState
from planning.hand.precontact import PreContactPlan, PreContactPlanner, PreContactSettings
from planning.pomdp.point_based import AlphaVectorPolicy
from planning.protocols import PlanResult


@dataclass(frozen=True)
class HandPlannerMemory:
    """What :class:`HandPlanner` remembers between decisions.

    Attributes:
        phase: ``pre-contact`` or ``post-contact``.
        trajectory: the pre-contact trajectory, once searched.
        step: how many of its actions have been sent.
    """

    phase: str
    trajectory: PreContactPlan | None = None
    step: int = 0


def _search_stats(plan: PreContactPlan) -> dict:
    return {"search": {"actions": list(plan.actions), "expansions": plan.expansions,
                       "seconds": plan.seconds, "reason": plan.reason}}


class HandPlanner:
    """``plan(belief, *, rng, contact_seen, memory) -> PlanResult``: an immutable core; its
    phase and trajectory position travel in :class:`HandPlannerMemory`.

    Args:
        model: the hand-relative POMDP.
        post_contact: the post-contact vectors.
        precontact: settings of the pre-contact search, or ``None`` to act with the
            post-contact policy from the start.
    """

    def __init__(self, model: HandPOMDP, post_contact: AlphaVectorPolicy,
                 precontact: PreContactSettings | None = PreContactSettings()):
        self.model = model
        self.post_contact = post_contact
        self._search = (None if precontact is None
                        else PreContactPlanner(model, post_contact, precontact))

    def plan(self, belief: ParticleBelief, *, rng: np.random.Generator,
             contact_seen: bool = False, memory: HandPlannerMemory | None = None,
             **_: object) -> PlanResult:
        """The next action for ``belief`` (object poses in the hand frame).

        Args:
            belief: the estimator's belief.
            rng: draws of the pre-contact search (on the call that searches).
            contact_seen: has the estimator seen contact (the switch to post-contact)?
            memory: the previous result's memory (``None`` on the first decision).
            **_: other context (``last_action``, ``reading``) is not needed: the belief
                carries it.

        Returns:
            The decision; its ``stats`` hold ``search`` on the call that searched.
        """
        start = time.perf_counter()
        if memory is None:
            memory = HandPlannerMemory(
                "pre-contact" if self._search is not None else "post-contact")
        stats: dict = {}
        values = self.post_contact.action_values(
            self.model.belief(np.asarray(belief.states), belief.weights))
        ranking = [int(a) for a in np.argsort(-values, kind="stable")]
        phase, trajectory, step = memory.phase, memory.trajectory, memory.step
        if phase == "pre-contact" and contact_seen:
            phase = "post-contact"
        if phase == "pre-contact":
            if trajectory is None:
                trajectory = self._search.plan(np.asarray(belief.states), belief.weights,
                                               rng=rng)
                stats = _search_stats(trajectory)
            if step < len(trajectory.actions):
                first = trajectory.actions[step]
                step += 1
                ranking = [first] + [a for a in ranking if a != first]
            else:
                phase = "post-contact"
        return PlanResult(ranking[0], tuple(ranking), phase,
                          1e3 * (time.perf_counter() - start), stats,
                          HandPlannerMemory(phase, trajectory, step))


class ThesisHandPlanner:
    """The thesis' execution behind the planner interface (see the module docstring).

    Args:
        model, post_contact, precontact: as :class:`HandPlanner`.
    """

    def __init__(self, model: HandPOMDP, post_contact: AlphaVectorPolicy,
                 precontact: PreContactSettings | None = PreContactSettings()):
        self.model = model
        self.post_contact = post_contact
        self._search = None if precontact is None else PreContactPlanner(model, post_contact,
                                                                         precontact)

    def plan(self, belief: ParticleBelief, *, rng: np.random.Generator,
             memory: HandPolicyState | None = None, last_action: int | None = None,
             reading: np.ndarray | None = None, **_: object) -> PlanResult:
        """The next action. The first call (``memory`` ``None``) starts the policy from
        ``belief``; every later one first updates the policy's belief (restored from
        ``memory``) with ``last_action`` (the action executed since, or ``None`` when none
        was) and ``reading`` ((S,) bool, taken after it); ``belief`` is then not used.

        Returns:
            The decision, as :meth:`HandPlanner.plan`; its memory is the policy's state.
        """
        start = time.perf_counter()
        stats: dict = {}
        policy = HandPolicy(self.model, self.post_contact, self._search)
        if memory is None:
            policy.reset(belief, rng=rng)
            if policy.plan is not None:
                stats = _search_stats(policy.plan)
        else:
            policy.restore(memory)
            if last_action is not None:
                policy.observe(last_action, np.asarray(reading, dtype=bool), rng=rng)
        action = policy.act()
        tracked = policy.discrete if policy.discrete is not None else \
            self.model.belief(np.asarray(policy.particles.states), policy.particles.weights)
        values = self.post_contact.action_values(tracked)
        ranking = [action] + [int(a) for a in np.argsort(-values, kind="stable") if a != action]
        return PlanResult(action, tuple(ranking), policy.phase,
                          1e3 * (time.perf_counter() - start), stats, policy.snapshot())
