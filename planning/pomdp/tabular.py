"""The tabular POMDP: what the offline solvers (QMDP, point-based) work on.

Shapes (S states, A actions, O observations):

- ``T[a]``: (S, S) sparse row-stochastic matrix, ``T[a][s, s'] = p(s' | s, a)``; sparse
  because the benchmarks (RockSample(7,8): 12,545 states) and the hand-relative model
  have a few successors per state;
- ``Z``: (A, S, O) dense, ``Z[a, s', o] = p(o | s', a)``;
- ``R``: (S, A) expected immediate reward;
- ``discount`` in [0, 1); ``initial``: (S,) belief.

The discrete Bayes filter over this model is :func:`belief_update`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from tqdm import tqdm

ROW_SUM_TOLERANCE = 1e-6


@dataclass(frozen=True)
class TabularPOMDP:
    """A finite POMDP (see the module docstring for shapes); validated on construction."""

    states: tuple[str, ...]
    actions: tuple[str, ...]
    observations: tuple[str, ...]
    T: tuple[sp.csr_matrix, ...]
    Z: np.ndarray
    R: np.ndarray
    discount: float
    initial: np.ndarray

    def __post_init__(self):
        S, A, n_obs = len(self.states), len(self.actions), len(self.observations)
        if len(self.T) != A or any(t.shape != (S, S) for t in self.T):
            raise ValueError(f"T must hold {A} matrices of shape ({S}, {S})")
        if self.Z.shape != (A, S, n_obs):
            raise ValueError(f"Z must have shape {(A, S, n_obs)}, got {self.Z.shape}")
        if self.R.shape != (S, A):
            raise ValueError(f"R must have shape {(S, A)}, got {self.R.shape}")
        if not 0.0 <= self.discount < 1.0:
            raise ValueError(f"discount must be in [0, 1), got {self.discount}")
        for a, t in enumerate(self.T):
            sums = np.asarray(t.sum(axis=1)).ravel()
            bad = np.flatnonzero(np.abs(sums - 1.0) > ROW_SUM_TOLERANCE)
            if len(bad):
                raise ValueError(f"T[{self.actions[a]}] row {self.states[bad[0]]} sums to "
                                 f"{sums[bad[0]]:.6g}, not 1")
        z_sums = self.Z.sum(axis=2)
        if np.any(np.abs(z_sums - 1.0) > ROW_SUM_TOLERANCE):
            a, s = np.argwhere(np.abs(z_sums - 1.0) > ROW_SUM_TOLERANCE)[0]
            raise ValueError(f"Z[{self.actions[a]}, {self.states[s]}] sums to "
                             f"{z_sums[a, s]:.6g}, not 1")
        if self.initial.shape != (S,) or abs(self.initial.sum() - 1.0) > ROW_SUM_TOLERANCE:
            raise ValueError("initial must be a probability vector over the states")

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S, A, O)."""
        return len(self.states), len(self.actions), len(self.observations)


def belief_update(pomdp: TabularPOMDP, belief: np.ndarray, action: int,
                  observation: int) -> tuple[np.ndarray, float]:
    """Discrete Bayes filter: b'(s') ~ Z[a, s', o] sum_s T[a][s, s'] b(s).

    Returns:
        (posterior (S,), p(o | b, a)); the posterior is the prediction when p(o | b, a) = 0.
    """
    predicted = pomdp.T[action].T @ belief
    joint = predicted * pomdp.Z[action, :, observation]
    total = float(joint.sum())
    if total <= 0.0:
        return predicted, 0.0
    return joint / total, total


def simulate_returns(pomdp: TabularPOMDP, policy, beliefs: np.ndarray, episodes: int,
                     horizon: int, *, rng: np.random.Generator,
                     progress: str | None = None) -> np.ndarray:
    """Discounted returns of ``policy`` (``act(belief) -> action``) on the model itself.

    Episode ``e`` starts from ``beliefs[e % K]`` ((K, S) initial beliefs): the state is drawn
    from it and the policy tracks it with the discrete Bayes filter for ``horizon`` steps.
    ``progress``: the label of a progress bar over the episodes (None: no bar; an online
    policy such as DESPOT can take tens of minutes for a few hundred episodes).

    Returns:
        (episodes,) returns.
    """
    beliefs = np.atleast_2d(beliefs)
    returns = np.empty(episodes)
    for e in tqdm(range(episodes), desc=progress, unit="episode", leave=False,
                  disable=progress is None):
        returns[e] = simulate_episode(pomdp, policy, beliefs[e % len(beliefs)], horizon,
                                      rng=rng)
    return returns


def simulate_episode(pomdp: TabularPOMDP, policy, belief: np.ndarray, horizon: int, *,
                     rng: np.random.Generator) -> float:
    """The discounted return of one episode of ``policy`` (``act(belief) -> action``) on the
    model itself: the state drawn from ``belief`` (S,), tracked by the discrete Bayes filter
    for ``horizon`` steps."""
    n_obs = pomdp.shape[2]
    belief = np.array(belief, dtype=float)
    state = int(rng.choice(len(belief), p=belief / belief.sum()))
    total, scale = 0.0, 1.0
    for _ in range(horizon):
        action = int(policy(belief))
        total += scale * pomdp.R[state, action]
        row = pomdp.T[action].getrow(state)
        state = int(rng.choice(row.indices, p=row.data / row.data.sum()))
        observation = int(rng.choice(n_obs, p=pomdp.Z[action, state]))
        belief, _ = belief_update(pomdp, belief, action, observation)
        scale *= pomdp.discount
    return total


def simulate_value(pomdp: TabularPOMDP, policy, episodes: int, horizon: int, *,
                   rng: np.random.Generator) -> tuple[float, float]:
    """Mean discounted return of ``policy`` over ``episodes`` episodes of ``horizon`` steps
    from the model's initial belief (see :func:`simulate_returns`).

    Returns:
        (mean, 95 % half-width).
    """
    returns = simulate_returns(pomdp, policy, pomdp.initial, episodes, horizon, rng=rng)
    half = 1.96 * returns.std(ddof=1) / np.sqrt(episodes) if episodes > 1 else 0.0
    return float(returns.mean()), float(half)
