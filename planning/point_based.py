"""A point-based POMDP solver of the SARSOP family: heuristic search for value iteration
(HSVI2, Smith and Simmons 2005), anytime, with both value bounds.

- Lower bound: alpha-vectors, started from the blind policies (one fixed action for
  ever) and improved by point-based backups at the beliefs the search visits.
- Upper bound: the fast informed bound (FIB, Hauskrecht 2000) at the belief simplex's
  corners, refined by belief-value points and read with the sawtooth interpolation.
- Search: from the initial belief, follow the action with the best upper bound and the
  observation with the largest weighted excess gap, ``p(o | b, a) (gap(b') - eps / g^t)``;
  stop when the gap there is below ``eps / g^t``; back up both bounds on the way back. The
  target ``eps`` follows the root gap (a fraction of it), so the solver stays anytime.
- Pruning: alpha-vectors that are best at none of the visited beliefs are dropped every
  ``prune_every`` backups.

Inside the search a belief is its support and the probabilities there; predictions gather
only the rows of T in the support, and only the chosen action's alpha-vector is built over
all states. That is what keeps RockSample(7,8) (12,545 states, beliefs over at most 256)
tractable. The per-node loops (expansion, the backup's choice, the new alpha, the sawtooth)
are compiled (:mod:`planning.point_based_kernels`): in numpy their many small calls cost
more than their arithmetic.
"""

from __future__ import annotations

import bisect
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from planning.point_based_kernels import (
    alpha_products,
    best_backup,
    compact_alphas,
    expand,
    new_alpha,
    sawtooth,
)
from planning.pomdp import TabularPOMDP
from planning.qmdp import solve_mdp


@dataclass(frozen=True)
class AlphaVectorPolicy:
    """A lower-bound policy: alpha-vectors (K, S), each with its action (K,)."""

    alphas: np.ndarray
    alpha_actions: np.ndarray
    action_names: tuple[str, ...]

    def value(self, belief: np.ndarray) -> float:
        return float(np.max(self.alphas @ belief))

    def act(self, belief: np.ndarray) -> int:
        return int(self.alpha_actions[np.argmax(self.alphas @ belief)])

    def action_values(self, belief: np.ndarray) -> np.ndarray:
        """(A,) the best vector value of each action at ``belief`` (-inf for an action
        with no vector): the order in which to fall back when the best is infeasible."""
        values = np.full(len(self.action_names), -np.inf)
        np.maximum.at(values, self.alpha_actions, self.alphas @ belief)
        return values

    def __call__(self, belief: np.ndarray) -> int:
        return self.act(belief)

    def save(self, path: str | Path) -> None:
        """Write the policy as ``.npz`` (alphas, actions, action names)."""
        np.savez_compressed(path, alphas=self.alphas, alpha_actions=self.alpha_actions,
                            action_names=np.array(self.action_names))

    @staticmethod
    def load(path: str | Path) -> AlphaVectorPolicy:
        data = np.load(path)
        return AlphaVectorPolicy(data["alphas"], data["alpha_actions"],
                                 tuple(str(n) for n in data["action_names"]))


class LookaheadPolicy:
    """Acts by one step of lookahead on the lower bound:
    ``argmax_a R(b, a) + g sum_o p(o | b, a) V_lower(b_ao)``.

    Executing the alpha-vector policy greedily can fall below the bound once pruning has
    removed the sub-plans of an alpha-vector; a lookahead step never chooses an action
    worth less than the bound at ``b`` (it contains the backup that produced it).
    """

    def __init__(self, pomdp: TabularPOMDP, policy: AlphaVectorPolicy):
        self.m = pomdp
        self.policy = policy

    def __call__(self, belief: np.ndarray) -> int:
        return self.act(belief)

    def act(self, belief: np.ndarray) -> int:
        values = belief @ self.m.R
        for a in range(self.m.shape[1]):
            predicted = self.m.T[a].T @ belief
            nz = np.flatnonzero(predicted)
            joint = predicted[nz][None, :] * self.m.Z[a, nz, :].T  # (O, |nz|) = p(o) b_ao
            best = (joint @ self.policy.alphas[:, nz].T).max(axis=1)
            values[a] += self.m.discount * best.sum()
        return int(np.argmax(values))


@dataclass
class SolverReport:
    """Bounds at the initial belief over time: rows of (elapsed s, lower, upper)."""

    history: list[tuple[float, float, float]] = field(default_factory=list)
    trials: int = 0
    backups: int = 0
    alpha_count: int = 0
    upper_points: int = 0

    def at(self, seconds: float) -> tuple[float, float]:
        """(lower, upper) as they stood at ``seconds`` (the last row not after it)."""
        rows = [r for r in self.history if r[0] <= seconds]
        row = rows[-1] if rows else self.history[0]
        return row[1], row[2]


class PointBasedSolver:
    """HSVI2-style solver (see the module docstring).

    Args:
        pomdp: the model.
        gap_fraction: each trial's target precision, as a fraction of the root gap.
        max_depth: deepest belief a trial visits.
        prune_every: prune the alpha-vectors after this many new ones.
    """

    def __init__(self, pomdp: TabularPOMDP, *, gap_fraction: float = 0.5,
                 max_depth: int = 250, prune_every: int = 200):
        self.m = pomdp
        S, A, n_obs = pomdp.shape
        self.gamma = pomdp.discount
        self.gap_fraction = gap_fraction
        self.max_depth = max_depth
        self.prune_every = prune_every
        # every T[a] in one CSR structure: row s of action a is entries indptr[a, s]:[a, s + 1]
        csr = [sp.csr_matrix(t, dtype=float) for t in pomdp.T]
        offsets = np.cumsum([0] + [t.nnz for t in csr[:-1]])
        self._T_indptr = np.stack([t.indptr.astype(np.int64) + o
                                   for t, o in zip(csr, offsets, strict=True)])
        self._T_indices = np.concatenate([t.indices for t in csr]).astype(np.int64)
        self._T_data = np.concatenate([t.data for t in csr])
        self._Z = np.ascontiguousarray(pomdp.Z, dtype=float)
        self._R = np.ascontiguousarray(pomdp.R, dtype=float)
        self._scratch = np.zeros(S)  # a dense belief, zero between uses (upper-bound points)
        self._accumulator = np.zeros(S)  # the same for the predictions of _expand
        self._touched = np.zeros(S, dtype=np.bool_)
        self.TZ = [[sp.csr_matrix(pomdp.T[a].multiply(pomdp.Z[a, :, o][None, :]))
                    for o in range(n_obs)] for a in range(A)]
        blind, blind_actions = self._blind_policies()
        # column-major: the search reads alphas[:, support], a few contiguous columns
        self._alpha_buffer = np.empty((max(64, 4 * len(blind)), S), order="F")
        self._action_buffer = np.empty(len(self._alpha_buffer), dtype=np.int64)
        self._alpha_count = 0
        for alpha, action in zip(blind, blind_actions, strict=True):
            self._add_alpha(alpha, action)
        self.corner = self._fast_informed_bound().max(axis=1)
        self.points = _UpperPoints()
        self.visited: list[tuple[np.ndarray, np.ndarray]] = []  # (support, probabilities)
        self._new_alphas = 0
        # at each visited belief pruning has compared: its best value and vector so far,
        # over the vectors [0, _pruned_alphas) that stood after the last pruning
        self._best_value = np.zeros(0)
        self._best_index = np.zeros(0, dtype=np.int64)
        self._pruned_alphas = 0
        self.report = SolverReport()

    @property
    def alphas(self) -> np.ndarray:
        """(K, S) the lower bound's alpha-vectors (a view)."""
        return self._alpha_buffer[:self._alpha_count]

    @property
    def alpha_actions(self) -> np.ndarray:
        """(K,) the action of each alpha-vector (a view)."""
        return self._action_buffer[:self._alpha_count]

    def _add_alpha(self, alpha: np.ndarray, action: int) -> None:
        """Append to the buffers, doubling them when full (no copy of all K per backup)."""
        if self._alpha_count == len(self._alpha_buffer):
            grown = np.empty((2 * len(self._alpha_buffer), self.m.shape[0]), order="F")
            grown[:self._alpha_count] = self._alpha_buffer
            self._alpha_buffer = grown
            self._action_buffer = np.concatenate([self._action_buffer,
                                                  np.empty_like(self._action_buffer)])
        self._alpha_buffer[self._alpha_count] = alpha
        self._action_buffer[self._alpha_count] = action
        self._alpha_count += 1

    # -- bounds
    def _blind_policies(self) -> tuple[np.ndarray, np.ndarray]:
        """Alpha of "always do a": V_a = R(:, a) + g T_a V_a, by iteration."""
        S, A, _ = self.m.shape
        alphas = np.empty((A, S))
        for a in range(A):
            worst = self.m.R[:, a].min() / (1 - self.gamma)
            v = np.full(S, worst)
            for _ in range(2000):
                new = self.m.R[:, a] + self.gamma * (self.m.T[a] @ v)
                if np.max(np.abs(new - v)) < 1e-6:
                    break
                v = new
            alphas[a] = new
        return alphas, np.arange(A)

    def _fast_informed_bound(self, tolerance: float = 1e-4) -> np.ndarray:
        """Q (S, A) of the FIB: R + g sum_o max_a' sum_s' T Z Q(s', a').

        Iterated from the MDP's Q, an upper bound on the FIB: the iteration only tightens
        it, and starts close."""
        S, A, n_obs = self.m.shape
        Q = solve_mdp(self.m)
        for _ in range(5000):
            new = self.m.R.copy()
            for a in range(A):
                for o in range(n_obs):
                    new[:, a] += self.gamma * (self.TZ[a][o] @ Q).max(axis=1)
            if np.max(np.abs(new - Q)) < tolerance:
                return new
            Q = new
        return Q

    # -- bounds at a belief. Inside the search a belief is local: its support (m,) (sorted
    # state indices) and the probabilities there (m,); every product runs over the support.
    def lower(self, belief: np.ndarray) -> float:
        return self._lower_local(*_local(belief))

    def upper(self, belief: np.ndarray) -> float:
        """Sawtooth interpolation over the corner values and the stored points."""
        support, probs = _local(belief)
        return float(self._upper_local(support, probs[None, :])[0])

    def _lower_local(self, support: np.ndarray, probs: np.ndarray) -> float:
        return float(np.max(self._products(support, probs[None, :])))

    def _products(self, columns: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """(R, K) products of (R, m) local beliefs on ``columns`` (m,) with every alpha."""
        return alpha_products(self._alpha_buffer, self._alpha_count, columns,
                               np.ascontiguousarray(rows))

    def _upper_local(self, support: np.ndarray, beliefs: np.ndarray) -> np.ndarray:
        """(K,) upper bounds of (K, m) beliefs that share the ``support`` (m,)."""
        return beliefs @ self.corner[support] + self.points.correction(support, beliefs,
                                                                       self._scratch)

    def _expand(self, support: np.ndarray, probs: np.ndarray) -> _Expansion:
        """Predictions and posteriors for every action (see :class:`_Expansion`); they
        gather only the rows of T in the support."""
        return _Expansion(*expand(self._T_indptr, self._T_indices, self._T_data, self._Z,
                                  support, probs, self._accumulator, self._touched))

    def _q_upper(self, support, probs, kids,
                 actions: range | list[int] | None = None) -> np.ndarray:
        """(A,) upper-bound Q(b, a); only for ``actions`` (default: all; the others are
        left at +inf)."""
        q = np.full(kids.actions, np.inf)
        rewards = probs @ self.m.R[support]
        for a in range(kids.actions) if actions is None else actions:
            nz, _, p, post = kids.action(a)
            possible = p > 0
            ups = self._upper_local(nz, post[possible]) if len(nz) else np.zeros(0)
            q[a] = rewards[a] + self.gamma * p[possible] @ ups
        return q

    # -- backups
    def _backup_lower(self, support, probs, kids) -> None:
        """Point-based backup: the value of every action is computed on the supports; only
        the best action's alpha-vector is built over all states."""
        rewards = probs @ self.m.R[support]
        best_value, best_action, best_choice = best_backup(
            self._alpha_buffer, self._alpha_count, kids.offsets, kids.states,
            kids.predicted, kids.p, kids.post, rewards, self.gamma)
        if best_value <= self._lower_local(support, probs) + 1e-9:
            return
        alpha = new_alpha(self._alpha_buffer, best_choice, best_action, self._T_indptr,
                          self._T_indices, self._T_data, self._Z, self._R, self.gamma)
        self._add_alpha(alpha, best_action)
        self.report.backups += 1
        self._new_alphas += 1
        if self._new_alphas >= self.prune_every:
            self._prune()

    def _backup_upper(self, support, probs, kids, q: np.ndarray, explored: int) -> None:
        """Back up the upper bound. Only the explored action's Q is recomputed: the others'
        children did not change, and an upper bound computed earlier stays an upper bound
        (the bound only tightens)."""
        q = q.copy()
        q[explored] = self._q_upper(support, probs, kids, [explored])[explored]
        value = float(q.max())
        if value < float(self._upper_local(support, probs[None, :])[0]) - 1e-9:
            self.points.add(support, probs, value - float(self.corner[support] @ probs))

    def _prune(self) -> None:
        """Keep the alpha-vectors that are best at some visited belief (and the blind ones).

        Incremental: each visited belief keeps its best alpha-vector from the last pruning,
        so only the vectors added since are compared at the beliefs seen before, and only
        the beliefs visited since are compared with every vector. The result is that of
        comparing all beliefs with all vectors, at a fraction of the products."""
        self._new_alphas = 0
        if not self.visited:
            return
        S, A, _ = self.m.shape
        count, fresh_from = self._alpha_count, self._pruned_alphas
        seen = len(self._best_value)
        rows = np.concatenate([np.full(len(sup), i) for i, (sup, _) in enumerate(self.visited)])
        B = sp.csr_matrix((np.concatenate([p for _, p in self.visited]),
                           (rows, np.concatenate([sup for sup, _ in self.visited]))),
                          shape=(len(self.visited), S))
        best_value = np.concatenate([self._best_value, np.full(len(self.visited) - seen,
                                                               -np.inf)])
        best_index = np.concatenate([self._best_index,
                                     np.zeros(len(self.visited) - seen, dtype=np.int64)])
        for beliefs, first in ((slice(0, seen), fresh_from), (slice(seen, None), 0)):
            if first >= count or beliefs.start == len(self.visited):
                continue
            values = np.asarray(B[beliefs] @ self.alphas[first:count].T)
            top = values.argmax(axis=1)
            top_value = values[np.arange(len(values)), top]
            better = top_value > best_value[beliefs]
            best_value[beliefs] = np.where(better, top_value, best_value[beliefs])
            best_index[beliefs] = np.where(better, first + top, best_index[beliefs])
        index = np.array(sorted(set(best_index.tolist()) | set(range(A))))
        renumber = np.full(count, -1, dtype=np.int64)
        renumber[index] = np.arange(len(index))
        compact_alphas(self._alpha_buffer.T, index)
        self._action_buffer[:len(index)] = self._action_buffer[index]
        self._alpha_count = len(index)
        self._best_value, self._best_index = best_value, renumber[best_index]
        self._pruned_alphas = len(index)

    # -- search
    def _explore(self, support: np.ndarray, probs: np.ndarray, epsilon: float,
                 depth: int) -> None:
        gap = (float(self._upper_local(support, probs[None, :])[0])
               - self._lower_local(support, probs))
        if gap <= epsilon * self.gamma ** (-depth) or depth >= self.max_depth:
            return
        if len(self.visited) < 5000:
            self.visited.append((support, probs))
        kids = self._expand(support, probs)
        q = self._q_upper(support, probs, kids)
        a = int(np.argmax(q))
        nz, _, p, post = kids.action(a)
        target = epsilon * self.gamma ** (-(depth + 1))
        scores = np.full(len(p), -np.inf)
        possible = p > 0
        ups = self._upper_local(nz, post[possible])
        lows = self._products(nz, post[possible]).max(axis=1)
        scores[possible] = p[possible] * (ups - lows - target)
        o = int(np.argmax(scores))
        keep = post[o] > 0
        self._explore(nz[keep], post[o][keep], epsilon, depth + 1)
        self._backup_lower(support, probs, kids)
        self._backup_upper(support, probs, kids, q, a)

    def solve(self, seconds: float, *, report_every: float = 1.0, callback=None,
              initial_beliefs: np.ndarray | None = None,
              weights: np.ndarray | None = None,
              max_trials: int | None = None) -> AlphaVectorPolicy:
        """Improve the bounds for ``seconds`` of wall time; return the lower-bound policy.

        Args:
            seconds: wall-time budget (s).
            report_every: how often (s) the bounds are recorded in :attr:`report`.
            callback: ``callback(elapsed, lower, upper)``, called at every record.
            initial_beliefs: (K, S) several initial beliefs to plan for at once (default:
                the model's one). This is the thesis' augmented POMDP (sec. 6.2.1): a
                fictitious first step that reveals which of the K beliefs holds, with
                probabilities ``weights``. Each trial starts at the belief with the largest
                weighted gap, which is where HSVI's observation choice at that first step
                would send it; the reported bounds are the weighted sums, without the
                fictitious step's discount.
            weights: (K,) probabilities of the initial beliefs (default: equal).
            max_trials: also stop after this many search trials. A wall-time budget makes
                the policy depend on the machine's speed; a trial budget makes it a
                function of the model alone (reproducible).
        """
        start = time.perf_counter()
        roots = (self.m.initial[None, :] if initial_beliefs is None
                 else np.atleast_2d(np.asarray(initial_beliefs, dtype=float)))
        if roots.shape[1] != self.m.shape[0]:
            raise ValueError(f"initial_beliefs must have {self.m.shape[0]} columns")
        w = (np.full(len(roots), 1.0 / len(roots)) if weights is None
             else np.asarray(weights, dtype=float) / np.sum(weights))
        last = -np.inf

        def bounds():
            lows = np.array([self.lower(b) for b in roots])
            ups = np.array([self.upper(b) for b in roots])
            return lows, ups

        def record(lows, ups):
            elapsed = time.perf_counter() - start
            lo, up = float(w @ lows), float(w @ ups)
            self.report.history.append((elapsed, lo, up))
            if callback is not None:
                callback(elapsed, lo, up)

        record(*bounds())
        trials = 0
        while time.perf_counter() - start < seconds and (max_trials is None
                                                         or trials < max_trials):
            trials += 1
            lows, ups = bounds()
            gaps = ups - lows
            if float(w @ gaps) < 1e-6:
                break
            k = int(np.argmax(w * gaps))
            self._explore(*_local(roots[k]), self.gap_fraction * gaps[k], 0)
            if time.perf_counter() - last >= report_every:
                record(*bounds())
                last = time.perf_counter()
        record(*bounds())
        self.report.trials = trials
        self.report.alpha_count = len(self.alphas)
        self.report.upper_points = len(self.points)
        return AlphaVectorPolicy(self.alphas.copy(), self.alpha_actions.copy(),
                                 self.m.actions)


class _UpperPoints:
    """Belief-value points of the upper bound, for the sawtooth:
    ``correction(b) = min(0, min_i excess_i * min_{s in supp b_i} b(s) / b_i(s))``.

    Only points whose support lies inside the belief's support can lower the bound (any
    other has a ratio of 0). Points are grouped by their smallest state index, and a
    belief looks only at the groups whose index lies in its support's range; structured
    models (RockSample, Tag: the robot's position is known, beliefs live in one block of
    states) then touch a small fraction of the points. A group's flat arrays are rebuilt
    only when a point joins it.
    """

    def __init__(self):
        self._groups: dict[int, _PointGroup] = {}
        self._keys: list[int] = []
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def add(self, support: np.ndarray, probs: np.ndarray, excess: float) -> None:
        key = int(support[0])
        if key not in self._groups:
            self._groups[key] = _PointGroup()
            bisect.insort(self._keys, key)
        self._groups[key].add(support, probs, excess)
        self._count += 1

    def correction(self, support: np.ndarray, beliefs: np.ndarray,
                   scratch: np.ndarray) -> np.ndarray:
        """(K,) sawtooth corrections (<= 0) for (K, m) beliefs on the sorted ``support``.

        ``scratch`` is an all-zero (S,) buffer: each belief is scattered into it to read
        its probabilities at a point's states, and it is zero again on return.
        """
        out = np.zeros(len(beliefs))
        if not self._count or len(support) == 0:
            return out
        begin, end = int(support[0]), int(support[-1])
        keys = self._keys[bisect.bisect_left(self._keys, begin):
                          bisect.bisect_right(self._keys, end)]
        if not keys:
            return out
        groups = [self._groups[key].flat() for key in keys]
        try:
            for k, belief in enumerate(beliefs):
                scratch[support] = belief
                for points, probs, starts, hi, excess in groups:
                    out[k] = min(out[k], sawtooth(points, probs, starts, hi, excess, end,
                                                   scratch))
        finally:
            scratch[support] = 0.0
        return out


class _PointGroup:
    """Upper-bound points that share their smallest state index, stored flat."""

    def __init__(self):
        self.supports: list[np.ndarray] = []
        self.probs: list[np.ndarray] = []
        self.excess: list[float] = []
        self._flat = None

    def add(self, support: np.ndarray, probs: np.ndarray, excess: float) -> None:
        self.supports.append(support)
        self.probs.append(probs.copy())
        self.excess.append(excess)
        self._flat = None

    def flat(self):
        """(states, probabilities, start offsets (n + 1,), largest state (n,), excess (n,))."""
        if self._flat is None:
            lengths = np.array([len(sup) for sup in self.supports])
            self._flat = (np.concatenate(self.supports), np.concatenate(self.probs),
                          np.concatenate([[0], np.cumsum(lengths)]),
                          np.array([sup[-1] for sup in self.supports]),
                          np.array(self.excess))
        return self._flat


@dataclass(frozen=True)
class _Expansion:
    """A belief's children, flat: action a owns entries ``offsets[a]:offsets[a + 1]`` of
    ``states`` (the prediction's support) and ``predicted`` (its probabilities), and those
    columns of ``post`` (O, total), the posteriors; ``p`` (A, O) are p(o | b, a)."""

    offsets: np.ndarray
    states: np.ndarray
    predicted: np.ndarray
    p: np.ndarray
    post: np.ndarray

    @property
    def actions(self) -> int:
        return len(self.offsets) - 1

    def action(self, a: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(support (m,), prediction (m,), p(o | b, a) (O,), posteriors (O, m))."""
        lo, hi = self.offsets[a], self.offsets[a + 1]
        return self.states[lo:hi], self.predicted[lo:hi], self.p[a], self.post[:, lo:hi]


def _local(belief: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A dense (S,) belief as (support, probabilities)."""
    support = np.flatnonzero(belief)
    return support, belief[support]
