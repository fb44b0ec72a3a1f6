"""The combined hand-relative policy a controller calls step by step (thesis sec. 6.1).

Before contact it follows the pre-contact trajectory from :mod:`planning.hand.precontact`
and tracks the belief with the conventional particle filter
(:mod:`estimation.particles.filters`); "once we observed contact, we switched to using a
discrete Bayes filter [...] This ensured that the belief update used during execution
matched that used during planning" (sec. 6.4.1). It also switches when the trajectory runs
out. The switch maps the particles to the discrete model (their predicted states) and
applies the contact observation there, so no particle-depletion problem arises at the
moment of contact.

>>> policy = HandPolicy(model, post_contact, planner)
>>> policy.reset(particles, rng=rng)
>>> a = policy.act(); ...; policy.observe(a, reading, rng=rng)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from planning.hand.model import HandPOMDP
from planning.hand.precontact import PreContactPlan, PreContactPlanner
from planning.pomdp.point_based import AlphaVectorPolicy
from planning.pomdp.tabular import belief_update


def qmdp_vectors(Q: np.ndarray, actions: tuple[str, ...]) -> AlphaVectorPolicy:
    """QMDP as a vector policy: one vector per action, ``Q[:, a]`` (thesis: "five
    alpha-vectors"), so QMDP and the point-based policy share one interface."""
    return AlphaVectorPolicy(np.ascontiguousarray(Q.T), np.arange(Q.shape[1]), actions)


@dataclass(frozen=True)
class HandPolicyState:
    """A :class:`HandPolicy`'s belief and place, as an immutable value
    (:meth:`HandPolicy.snapshot`, :meth:`HandPolicy.restore`).

    Attributes:
        plan: the pre-contact trajectory (``None`` without a pre-contact planner).
        particles: the particle belief before contact, else ``None``.
        discrete: (S,) read-only, the discrete belief after contact, else ``None``.
        step: how many of the trajectory's actions have been observed.
    """

    plan: PreContactPlan | None
    particles: ParticleBelief | None
    discrete: np.ndarray | None
    step: int

    def __deepcopy__(self, memo) -> HandPolicyState:
        return self  # immutable: a copy would be the same value


class HandPolicy:
    """Pre-contact trajectory, then the post-contact policy.

    Args:
        model: the hand-relative POMDP.
        post_contact: the post-contact vectors (QMDP or point-based).
        planner: the pre-contact planner, or None for a post-contact policy alone (the
            belief is then discretised at once).
    """

    def __init__(self, model: HandPOMDP, post_contact: AlphaVectorPolicy,
                 planner: PreContactPlanner | None = None):
        self.model = model
        self.post_contact = post_contact
        self.planner = planner
        self._filter = make_filter("cpf", model.world)
        self.plan: PreContactPlan | None = None
        self.particles: ParticleBelief | None = None
        self.discrete: np.ndarray | None = None
        self._step = 0

    @property
    def phase(self) -> str:
        """``"pre-contact"`` or ``"post-contact"``."""
        return "post-contact" if self.discrete is not None else "pre-contact"

    def reset(self, belief: ParticleBelief | np.ndarray, *, rng: np.random.Generator,
              plan: PreContactPlan | None = None) -> None:
        """Start from a particle belief (poses (N, 3) or a ParticleBelief) or a discrete one
        ((S,) over the model's states). ``plan``: a pre-contact trajectory already searched
        for this belief (the search is deterministic given the belief and its seed, so
        trials from one belief share it)."""
        self._step = 0
        self.plan = None
        if isinstance(belief, np.ndarray) and belief.ndim == 1:
            self.discrete, self.particles = belief.copy(), None
            return
        particles = belief if isinstance(belief, ParticleBelief) else ParticleBelief.uniform(
            np.asarray(belief, dtype=float))
        self.particles, self.discrete = particles, None
        if self.planner is None:
            self._switch()
            return
        self.plan = plan if plan is not None else self.planner.plan(
            particles.states, particles.weights, rng=rng)
        if not self.plan.actions:
            self._switch()

    def snapshot(self) -> HandPolicyState:
        """The policy's state as a value; :meth:`restore` brings it back."""
        discrete = None
        if self.discrete is not None:
            discrete = self.discrete.copy()
            discrete.setflags(write=False)
        return HandPolicyState(self.plan, self.particles, discrete, self._step)

    def restore(self, state: HandPolicyState) -> None:
        """Continue from a :meth:`snapshot`."""
        self.plan, self.particles, self._step = state.plan, state.particles, state.step
        self.discrete = None if state.discrete is None else state.discrete.copy()

    def act(self, belief: ParticleBelief | np.ndarray | None = None, *,
            rng: np.random.Generator | None = None) -> int:
        """The next action index; a ``belief`` given here replaces the tracked one (and
        re-plans before contact, which needs ``rng``)."""
        if belief is not None:
            if rng is None:
                raise ValueError("act(belief) restarts the policy from that belief; pass rng")
            self.reset(belief, rng=rng)
        if self.discrete is not None:
            return self.post_contact.act(self.discrete)
        return self.plan.actions[self._step]

    def observe(self, action: int, observation: np.ndarray, *,
                rng: np.random.Generator) -> None:
        """Update the belief with the action taken and the (S,) boolean reading."""
        m = self.model
        o = m.observation_index(observation)
        if self.discrete is not None:
            self.discrete, _ = belief_update(m.pomdp, self.discrete, action, o)
            return
        a_vec = m.spec.action_vectors()[action]
        self._step += 1
        if o != 0 or self._step >= len(self.plan.actions):
            predicted = m.world.sample_step(self.particles.states, a_vec, rng=rng)
            prior = m.belief(predicted, self.particles.weights)
            joint = prior * m.pomdp.Z[action, :, o]
            self.discrete = joint / joint.sum() if joint.sum() > 0 else prior
            self.particles = None
            return
        self.particles, _ = self._filter.update(self.particles, a_vec, observation, rng=rng)

    def _switch(self) -> None:
        self.discrete = self.model.belief(self.particles.states, self.particles.weights)
        self.particles = None
