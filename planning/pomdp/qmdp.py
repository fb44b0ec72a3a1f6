"""QMDP (Littman, Cassandra, Kaelbling 1995): solve the fully observable MDP by value
iteration, then act greedily on the belief-weighted action values. It assumes all state
uncertainty vanishes after one step, so it never chooses an action for the information it
gathers: the thesis' baseline for the post-contact policy (sec. 6.4.2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planning.pomdp.tabular import TabularPOMDP


@dataclass(frozen=True)
class QMDPPolicy:
    """Q: (S, A) action values of the underlying MDP."""

    Q: np.ndarray
    actions: tuple[str, ...]

    def action_values(self, belief: np.ndarray) -> np.ndarray:
        """(A,) b . Q[:, a]."""
        return belief @ self.Q

    def act(self, belief: np.ndarray) -> int:
        """The action with the largest belief-weighted value."""
        return int(np.argmax(self.action_values(belief)))

    def __call__(self, belief: np.ndarray) -> int:
        return self.act(belief)


def solve_mdp(pomdp: TabularPOMDP, *, tolerance: float = 1e-6,
              max_iterations: int = 100_000) -> np.ndarray:
    """(S, A) optimal Q of the underlying MDP, to ``tolerance`` in the max norm of V."""
    gamma = pomdp.discount
    V = np.zeros(len(pomdp.states))
    stop = tolerance * (1 - gamma) / max(2 * gamma, 1e-12)
    for _ in range(max_iterations):
        Q = pomdp.R + gamma * np.column_stack([t @ V for t in pomdp.T])
        V_new = Q.max(axis=1)
        if np.max(np.abs(V_new - V)) < stop:
            return Q
        V = V_new
    raise RuntimeError(f"value iteration did not converge in {max_iterations} iterations")


def mdp_horizon_values(pomdp: TabularPOMDP, horizon: int) -> np.ndarray:
    """(S,) the optimal values of the underlying MDP over ``horizon`` steps (``horizon``
    Bellman backups from V = 0): ``b . V`` bounds from above the ``horizon``-step value of
    any policy of the POMDP from belief b (it is what a policy that saw the state would
    get). Where every reward is at most 0 a finite horizon's value is at least the infinite
    one's, so an episode of ``horizon`` steps is judged against this bound and not against
    :func:`solve_mdp`'s."""
    V = np.zeros(len(pomdp.states))
    for _ in range(horizon):
        V = (pomdp.R + pomdp.discount * np.column_stack([t @ V for t in pomdp.T])).max(axis=1)
    return V


def qmdp_policy(pomdp: TabularPOMDP, **kwargs) -> QMDPPolicy:
    """The QMDP policy of ``pomdp``."""
    return QMDPPolicy(solve_mdp(pomdp, **kwargs), pomdp.actions)
