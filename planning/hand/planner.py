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
"""

from __future__ import annotations

import time

import numpy as np

from estimation.particles.belief import ParticleBelief
from planning.hand.model import HandPOMDP
from planning.hand.policy import HandPolicy
from planning.hand.precontact import PreContactPlan, PreContactPlanner, PreContactSettings
from planning.pomdp.point_based import AlphaVectorPolicy


class HandPlanner:
    """``plan(belief, *, contact_seen, rng) -> (action, stats)``.

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
        self.trajectory: PreContactPlan | None = None
        self.phase = "pre-contact" if precontact is not None else "post-contact"
        self._step = 0

    def plan(self, belief: ParticleBelief, *, contact_seen: bool, rng: np.random.Generator,
             last_action: int | None = None,
             reading: np.ndarray | None = None) -> tuple[int, dict]:
        """The next action for ``belief`` (object poses in the hand frame); ``last_action``
        and ``reading`` are not needed here (the belief carries them).

        Returns:
            ``(action index, stats)``; stats: ``phase``, ``ranking`` (every action, best
            first), ``planning_ms`` (wall time of this call, including the search when it
            ran), and, on the call that searched, ``search`` (its actions, expansions,
            seconds and stop reason).
        """
        start = time.perf_counter()
        stats: dict = {}
        values = self.post_contact.action_values(
            self.model.belief(np.asarray(belief.states), belief.weights))
        ranking = [int(a) for a in np.argsort(-values, kind="stable")]
        if self.phase == "pre-contact" and contact_seen:
            self.phase = "post-contact"
        if self.phase == "pre-contact":
            if self.trajectory is None:
                self.trajectory = self._search.plan(np.asarray(belief.states), belief.weights,
                                                    rng=rng)
                stats["search"] = {"actions": list(self.trajectory.actions),
                                   "expansions": self.trajectory.expansions,
                                   "seconds": self.trajectory.seconds,
                                   "reason": self.trajectory.reason}
            if self._step < len(self.trajectory.actions):
                first = self.trajectory.actions[self._step]
                self._step += 1
                ranking = [first] + [a for a in ranking if a != first]
            else:
                self.phase = "post-contact"
        stats.update(phase=self.phase, ranking=ranking,
                     planning_ms=1e3 * (time.perf_counter() - start))
        return ranking[0], stats


class ThesisHandPlanner:
    """The thesis' execution behind the planner interface (see the module docstring).

    Args:
        model, post_contact, precontact: as :class:`HandPlanner`.
    """

    def __init__(self, model: HandPOMDP, post_contact: AlphaVectorPolicy,
                 precontact: PreContactSettings | None = PreContactSettings()):
        self.model = model
        self.post_contact = post_contact
        search = None if precontact is None else PreContactPlanner(model, post_contact,
                                                                   precontact)
        self.policy = HandPolicy(model, post_contact, search)
        self._started = False

    def plan(self, belief: ParticleBelief, *, contact_seen: bool, rng: np.random.Generator,
             last_action: int | None = None,
             reading: np.ndarray | None = None) -> tuple[int, dict]:
        """The next action. The first call starts the policy from ``belief``; every later
        one first updates the policy's belief with ``last_action`` (the action executed
        since, or ``None`` when none was) and ``reading`` ((S,) bool, taken after it);
        ``belief`` and ``contact_seen`` are then not used.

        Returns:
            ``(action index, stats)`` as :meth:`HandPlanner.plan`.
        """
        start = time.perf_counter()
        stats: dict = {}
        if not self._started:
            self.policy.reset(belief, rng=rng)
            self._started = True
            if self.policy.plan is not None:
                stats["search"] = {"actions": list(self.policy.plan.actions),
                                   "expansions": self.policy.plan.expansions,
                                   "seconds": self.policy.plan.seconds,
                                   "reason": self.policy.plan.reason}
        elif last_action is not None:
            self.policy.observe(last_action, np.asarray(reading, dtype=bool), rng=rng)
        action = self.policy.act()
        tracked = self.policy.discrete if self.policy.discrete is not None else \
            self.model.belief(np.asarray(self.policy.particles.states),
                              self.policy.particles.weights)
        values = self.post_contact.action_values(tracked)
        ranking = [action] + [int(a) for a in np.argsort(-values, kind="stable") if a != action]
        stats.update(phase=self.policy.phase, ranking=ranking,
                     planning_ms=1e3 * (time.perf_counter() - start))
        return action, stats
