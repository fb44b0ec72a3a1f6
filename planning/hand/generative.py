"""The hand-relative problem on the continuous planar model as a generative POMDP, for
DESPOT planning without the discretisation (beyond the thesis' Rel-DESPOT, sec. 7.3.3).

The thesis' Rel-DESPOT plans on the discrete Rel-POMDP, as Rel-QMDP and Rel-SARSOP do. DESPOT
needs no tables, only a simulator, so it can plan on the model the discrete one was sampled
from: :class:`ContinuousHandGenerative` steps K scenarios' object poses (x m, y m, theta
rad; hand frame) with the quasi-static pushing model of :mod:`models.planar.pushing` and
reads the binary contact sensors of :mod:`models.planar.observation`, each deterministic
given the scenario's uniforms. What it keeps from the discrete model is only the guidance
the thesis gives DESPOT (Rel-QMDP as upper bound and as rollout policy):

- reward ``R(s, a) = 0`` if the object's centre lies in the goal region, else -1 (thesis
  sec. 3.4; the discrete model's reward is this one's mean over a cell);
- upper bound: the MDP value of the discrete cell holding each scenario's pose (Rel-QMDP's
  V); outside the trust region, the sentinel's -1 / (1 - gamma). On the continuous model it
  is a heuristic, not a proof: crossings are repaired and counted by the search;
- default (rollout) policy, node-level: the action of largest QMDP value summed over the
  cells of the node's scenarios (Rel-QMDP on the node's particle set). ``rollout="discrete"``
  (default) rolls it out on the discrete model from each scenario's cell, with the
  scenario's own uniforms (the compiled tabular rollout: microseconds a node);
  ``rollout="continuous"`` rolls it out on the continuous model (the faithful lower bound of
  this model, about 2 ms per depth for 400 rows, so 90-step rollouts cost about 0.2 s an
  expansion here; measured with :mod:`experiments.latdespot_study`'s settings).

No state is terminal: the goal is not absorbing (the object can be pushed out again), and
a pose outside the trust region keeps being simulated (the discrete model's sentinel is
absorbing; here the object may come back, which the upper bound does not know).

The uniforms of one step: ``2 * substeps`` for the push (the longest action's) and two for
the observation (:meth:`~models.planar.observation.ContactObservationModel.sample_observation`).
"""

from __future__ import annotations

import numpy as np

from models.planar.observation import observation_keys, observation_reading
from planning.hand.beliefs import GaussianBelief
from planning.hand.model import HandPOMDP
from planning.pomdp.generative import GenerativeStep, TabularGenerative, action_array

ROLLOUTS = ("discrete", "continuous")
OBSERVATION_UNIFORMS = 2


class ContinuousHandGenerative:
    """See the module docstring.

    Args:
        model: the discrete hand-relative POMDP (its world, goal, actions, discount, and the
            Rel-QMDP bound and rollout policy).
        initial: the initial belief (for :meth:`sample_initial`).
        rollout: ``discrete`` or ``continuous`` (see the module docstring).
    """

    def __init__(self, model: HandPOMDP, initial: GaussianBelief, *,
                 rollout: str = "discrete"):
        if rollout not in ROLLOUTS:
            raise ValueError(f"rollout must be one of {ROLLOUTS}, got {rollout!r}")
        self.model = model
        self.world = model.world
        self.initial = initial
        self.discount = model.pomdp.discount
        self.actions = model.pomdp.actions
        self.vectors = model.spec.action_vectors()
        self._push_uniforms = np.array([self.world.uniforms_per_step(v) for v in self.vectors])
        self.uniforms_per_step = int(self._push_uniforms.max()) + OBSERVATION_UNIFORMS
        self._tabular = TabularGenerative(model.pomdp, default_policy="qmdp")
        self.rollout_mode = rollout
        if rollout == "continuous":  # the search then steps this model (no kernel)
            self.rollout = None

    def step(self, states: np.ndarray, actions: int | np.ndarray,
             u: np.ndarray) -> GenerativeStep:
        """Push each scenario's object by its action (one push call per distinct action)
        and read the sensors after it; reward of the pose before the push."""
        states = np.asarray(states, dtype=float)
        a = action_array(actions, len(states))
        next_states = np.empty_like(states)
        for action in np.unique(a):
            rows = np.flatnonzero(a == action)
            width = self._push_uniforms[action]
            next_states[rows] = self.world.step(states[rows], self.vectors[action],
                                                u[rows, :width])
        readings = self.world.sample_observation(next_states, u[:, -OBSERVATION_UNIFORMS:])
        rewards = self.model.in_goal(states) - 1.0
        return GenerativeStep(next_states, rewards, observation_keys(readings),
                              np.zeros(len(states), dtype=bool))

    def log_likelihood(self, observation: int, states: np.ndarray,
                       action: int) -> np.ndarray:
        reading = observation_reading(observation, self.world.sensor_count)
        return self.world.log_likelihood(reading, np.asarray(states),
                                         self.vectors[action])

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        return self.initial.sample(self.world, n, rng=rng)

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        return np.zeros(len(states), dtype=bool)

    def cells(self, states: np.ndarray) -> np.ndarray:
        """(K, 1) int64 discrete states (cells) of poses (K, 3)."""
        return self.model.index(np.asarray(states, dtype=float))[:, None]

    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        return self._tabular.upper_bound(self.cells(states))

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        return self._tabular.default_actions(self.cells(states))

    def rollout(self, states, scenarios, depths, offsets, uniforms, max_depth) -> np.ndarray:
        """Rel-QMDP's returns on the discrete model from each scenario's cell (the
        ``discrete`` rollout; see :func:`planning.pomdp.generative.rollout_kernel`)."""
        return self._tabular.rollout(self.cells(states), scenarios, depths, offsets,
                                     uniforms, max_depth)
