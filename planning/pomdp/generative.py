"""Generative POMDPs: the seam DESPOT plans on (DESIGN.md, "Generative POMDP").

A generative POMDP steps K *scenarios* at once: ``step(states (K, d), actions, u (K, U))``
returns the next states, rewards, observations and terminal flags, deterministic given the
pre-drawn uniforms ``u`` (U = :attr:`~GenerativePOMDP.uniforms_per_step`). That
determinism is what makes a DESPOT scenario (a start state and its own stream of
uniforms) replayable down every branch of the tree (Ye et al., JAIR 2017, sec. 3).
``actions`` is one action index for all K or a (K,) array, one per scenario (rollouts of a
default policy give each scenario its own action). Observations are integer codes.

Terminal states are absorbing with zero reward: stepping one returns it unchanged,
reward 0, ``terminal`` True.

:class:`TabularGenerative` wraps any :class:`~planning.pomdp.tabular.TabularPOMDP`
(inverse-CDF sampling of the successor and the observation from two uniforms), so every
``.pomdp`` file runs through DESPOT unchanged; :mod:`planning.pomdp.tag` and
:mod:`planning.pomdp.rocksample` are native batched models of the field's benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from planning.pomdp.generative_kernels import (
    tabular_blind_rollout,
    tabular_qmdp_rollout,
    tabular_qmdp_rollouts,
    tabular_rollout,
    tabular_step,
    tabular_upper,
)
from planning.pomdp.qmdp import solve_mdp
from planning.pomdp.tabular import TabularPOMDP

DEFAULT_POLICIES = ("blind", "qmdp")


@dataclass(frozen=True)
class GenerativeStep:
    """K scenarios stepped at once.

    Attributes:
        next_states: (K, d).
        rewards: (K,).
        observations: (K,) int64 observation codes.
        terminal: (K,) bool: the next state is terminal (absorbing, zero reward).
    """

    next_states: np.ndarray
    rewards: np.ndarray
    observations: np.ndarray
    terminal: np.ndarray


@runtime_checkable
class GenerativePOMDP(Protocol):
    """What DESPOT and the particle belief between its decisions need.

    Attributes:
        discount: gamma in [0, 1).
        actions: the action names (their indices are the actions).
        uniforms_per_step: U, the uniforms one scenario's step consumes.
    """

    discount: float
    actions: tuple[str, ...]
    uniforms_per_step: int

    def step(self, states: np.ndarray, actions: int | np.ndarray,
             u: np.ndarray) -> GenerativeStep:
        """K scenarios under ``actions`` (one, or (K,)), deterministic given ``u`` (K, U)."""

    def log_likelihood(self, observation: int, states: np.ndarray,
                       action: int) -> np.ndarray:
        """(K,) ``log p(observation | next state, action)`` (-inf where impossible)."""

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        """(n, d) states drawn from the initial belief."""

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        """(K,) bool."""

    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        """(K,) an upper bound on the optimal value from each state, knowing it (e.g. the
        MDP value): DESPOT's default upper bound."""

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        """(K,) the default (rollout) policy's actions for the states of one node's K
        scenarios at one depth: DESPOT's lower bound is this policy's return. It may use
        the set (e.g. act on its most frequent state, as the reference's particle-set
        policies do) and each scenario's observable part (e.g. the robot's own cell), but
        no scenario's hidden part, or the lower bound would not be one."""


def rollout_kernel(model):
    """The model's compiled rollout of its default policy, if it has one: ``rollout(states
    (M, d), scenarios (M,), depths (M,), offsets (J + 1,), uniforms (K, D + 1, U),
    max_depth) -> (M,)`` discounted returns, rows ``offsets[j]:offsets[j + 1]`` being one
    node's scenarios; the same returns as stepping
    :meth:`GenerativePOMDP.default_actions` node by node, depth by depth, with each
    scenario's uniforms."""
    return getattr(model, "rollout", None)


def action_array(actions: int | np.ndarray, count: int) -> np.ndarray:
    """(count,) int64 actions from one action or an array of them."""
    out = np.asarray(actions, dtype=np.int64)
    return np.full(count, int(out)) if out.ndim == 0 else out


def inverse_cdf(cumulative: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(K,) index of the first column of ``cumulative`` (K, n) (row-wise cumulative
    probabilities) that exceeds ``u`` (K,); clipped to the last column against rounding."""
    index = (u[:, None] >= cumulative).sum(axis=1)
    return np.minimum(index, cumulative.shape[1] - 1)


class TabularGenerative:
    """A :class:`TabularPOMDP` as a generative POMDP; a state is its index (column 0 of a
    (K, 1) int64 array).

    ``u[:, 0]`` draws the successor by inverse CDF over the row ``T[a][s]``, ``u[:, 1]`` the
    observation over ``Z[a, s']``. A state is terminal if every action keeps it with
    probability 1 at zero reward (Tag's "tagged", RockSample's "exit"). The upper bound is
    the MDP value (:func:`~planning.pomdp.qmdp.solve_mdp`). The default policy is
    ``blind``: the best blind policy (one action forever, the best from the initial
    belief), which observes nothing; or ``qmdp``: at each depth of a rollout, the action of
    largest QMDP value summed over the node's scenarios (QMDP on the node's particle set,
    open loop below it; the thesis' Rel-DESPOT rolls out Rel-QMDP, sec. 7.3.3). Both use
    nothing a scenario hides, so their returns are lower bounds.
    """

    uniforms_per_step = 2

    def __init__(self, pomdp: TabularPOMDP, *, default_policy: str = "blind"):
        if default_policy not in DEFAULT_POLICIES:
            raise ValueError(f"default_policy must be one of {DEFAULT_POLICIES}, got "
                             f"{default_policy!r}")
        self.default_policy = default_policy
        self.pomdp = pomdp
        self.discount = pomdp.discount
        self.actions = pomdp.actions
        S, A, _ = pomdp.shape
        self._successors = []  # per action: (indptr, indices, global cumulative)
        for t in pomdp.T:
            t = t.tocsr()
            t.sort_indices()
            self._successors.append((t.indptr, t.indices, np.cumsum(t.data)))
        self._cum_z = np.cumsum(pomdp.Z, axis=2)
        stays = np.ones(S, dtype=bool)
        for t in pomdp.T:
            stays &= np.isclose(t.diagonal(), 1.0)
        self._terminal = stays & np.all(pomdp.R == 0.0, axis=1)
        self._q = solve_mdp(pomdp)
        self._v = self._q.max(axis=1)
        self._blind = self._best_blind_action()
        self._stacked = self._stack_rows()
        self.rollout(np.zeros((1, 1), dtype=np.int64), np.zeros(1, dtype=np.int64),
                     np.zeros(1, dtype=np.int64), np.array([0, 1]),
                     np.zeros((1, 2, 2)), 1)  # compile (or load the cached kernel) now

    @property
    def q_values(self) -> np.ndarray:
        """(S, A) the MDP's Q (QMDP's action values; the upper bound is their max)."""
        return self._q

    def _best_blind_action(self) -> int:
        """The action whose repetition forever has the largest value at the initial belief."""
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        S = len(self.pomdp.states)
        values = []
        for a, t in enumerate(self.pomdp.T):
            v = spla.spsolve((sp.identity(S, format="csc") - self.discount * t).tocsc(),
                             self.pomdp.R[:, a])
            values.append(float(self.pomdp.initial @ v))
        return int(np.argmax(values))

    def step(self, states: np.ndarray, actions: int | np.ndarray,
             u: np.ndarray) -> GenerativeStep:
        s = np.asarray(states, dtype=np.int64)[:, 0]
        a = action_array(actions, len(s))
        next_s = np.empty_like(s)
        for action in np.unique(a):
            rows = np.flatnonzero(a == action)
            indptr, indices, cum = self._successors[action]
            start, stop = indptr[s[rows]], indptr[s[rows] + 1]
            base = np.where(start > 0, cum[np.maximum(start - 1, 0)], 0.0)
            target = base + u[rows, 0] * (cum[stop - 1] - base)
            k = np.searchsorted(cum, target, side="right")
            next_s[rows] = indices[np.clip(k, start, stop - 1)]
        observations = inverse_cdf(self._cum_z[a, next_s], u[:, 1])
        rewards = self.pomdp.R[s, a]
        return GenerativeStep(next_s[:, None], rewards, observations, self._terminal[next_s])

    def log_likelihood(self, observation: int, states: np.ndarray,
                       action: int) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return np.log(self.pomdp.Z[action, np.asarray(states)[:, 0], observation])

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        return rng.choice(len(self.pomdp.states), size=n, p=self.pomdp.initial)[:, None]

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        return self._terminal[np.asarray(states)[:, 0]]

    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        return self._v[np.asarray(states)[:, 0]]

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        if self.default_policy == "qmdp":
            live = np.asarray(states)[:, 0]
            return np.full(len(states), int(np.argmax(self._q[live].sum(axis=0))),
                           dtype=np.int64)
        return np.full(len(states), self._blind, dtype=np.int64)

    def _stack_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every T[a]'s CSR arrays stacked per action (padded): (A, S + 1), (A, W), (A, W)."""
        width = max(len(indices) for _, indices, _ in self._successors)
        indptr = np.stack([ip for ip, _, _ in self._successors]).astype(np.int64)
        indices = np.zeros((len(self.actions), width), dtype=np.int64)
        cumulative = np.zeros((len(self.actions), width))
        for a, (_, idx, cum) in enumerate(self._successors):
            indices[a, :len(idx)], cumulative[a, :len(cum)] = idx, cum
        return indptr, indices, cumulative

    def kernels(self):
        """The compiled DESPOT's kernels (:func:`planning.pomdp.despot_kernels.make_core`)
        and their parameters."""
        rollout = tabular_qmdp_rollout if self.default_policy == "qmdp" else tabular_rollout
        return (tabular_step, tabular_upper, rollout), (
            *self._stacked, self._cum_z, self.pomdp.R, self._terminal, self._v,
            int(self._blind), self._q)

    def rollout(self, states, scenarios, depths, offsets, uniforms, max_depth) -> np.ndarray:
        """The default policy's returns, compiled (see :func:`rollout_kernel`)."""
        if self.default_policy == "qmdp":
            return tabular_qmdp_rollouts(
                np.asarray(states, dtype=float), scenarios, depths, offsets, uniforms,
                max_depth, self.discount, *self._stacked, self.pomdp.R, self._terminal,
                self._q)
        indptr, indices, cumulative = self._successors[self._blind]
        index = np.ascontiguousarray(np.asarray(states)[:, 0])
        return tabular_blind_rollout(index, scenarios, depths, uniforms, max_depth,
                                     self.discount, self._blind, indptr, indices, cumulative,
                                     self.pomdp.R, self._terminal)
