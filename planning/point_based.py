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

Beliefs are dense (S,) vectors but every product uses their support only, which is what
keeps RockSample(7,8) (12,545 states, beliefs over at most 256) tractable in numpy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

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
        self.TZ = [[sp.csr_matrix(pomdp.T[a].multiply(pomdp.Z[a, :, o][None, :]))
                    for o in range(n_obs)] for a in range(A)]
        blind, blind_actions = self._blind_policies()
        self._alpha_buffer = np.empty((max(64, 4 * len(blind)), S))
        self._action_buffer = np.empty(len(self._alpha_buffer), dtype=np.int64)
        self._alpha_count = 0
        for alpha, action in zip(blind, blind_actions, strict=True):
            self._add_alpha(alpha, action)
        self.corner = self._fast_informed_bound().max(axis=1)
        self.points = _UpperPoints()
        self.visited: list[tuple[np.ndarray, np.ndarray]] = []  # (support, probabilities)
        self._new_alphas = 0
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
            self._alpha_buffer = np.concatenate([self._alpha_buffer,
                                                 np.empty_like(self._alpha_buffer)])
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

    def lower(self, belief: np.ndarray) -> float:
        support = np.flatnonzero(belief)
        return float(np.max(self.alphas[:, support] @ belief[support]))

    def upper(self, belief: np.ndarray) -> float:
        """Sawtooth interpolation over the corner values and the stored points."""
        return float(self.upper_many(belief[None, :])[0])

    def upper_many(self, beliefs: np.ndarray, span: tuple[int, int] | None = None) -> np.ndarray:
        """(K,) sawtooth upper bounds of (K, S) beliefs; ``span`` = (first, last) state index
        that any of them can be non-zero at, when the caller knows it."""
        return beliefs @ self.corner + self.points.correction(beliefs, span)

    def _expand(self, belief: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per action: (predicted belief (S,), p(o | b, a) (O,), posteriors (O, S)); the
        products run over the predicted belief's support only."""
        S, A, n_obs = self.m.shape
        out = []
        for a in range(A):
            predicted = self.m.T[a].T @ belief
            nz = np.flatnonzero(predicted)
            joint = predicted[nz][None, :] * self.m.Z[a, nz, :].T  # (O, |nz|)
            p = joint.sum(axis=1)
            post = np.zeros((n_obs, S))
            possible = p > 0
            post[np.ix_(possible, nz)] = joint[possible] / p[possible, None]
            out.append((predicted, p, post))
        return out

    def _q_upper(self, belief: np.ndarray, kids) -> tuple[np.ndarray, list[np.ndarray]]:
        """Upper-bound Q(b, a) for every action and the children's upper bounds (A x (O,))."""
        A = self.m.shape[1]
        q = np.empty(A)
        r = belief @ self.m.R
        ups_all = []
        for a, (predicted, p, post) in enumerate(kids):
            ups = np.zeros(len(p))
            possible = p > 0
            nz = np.flatnonzero(predicted)
            if len(nz):
                ups[possible] = self.upper_many(post[possible], (int(nz[0]), int(nz[-1])))
            q[a] = r[a] + self.gamma * p @ ups
            ups_all.append(ups)
        return q, ups_all

    # -- backups
    def _backup_lower(self, belief: np.ndarray, kids) -> None:
        S, A, n_obs = self.m.shape
        support = np.flatnonzero(belief)
        best_value, best_alpha, best_action = -np.inf, None, -1
        for a, (predicted, p, post) in enumerate(kids):
            g = np.zeros(S)
            pnz = np.flatnonzero(predicted)
            # the best alpha at every posterior; impossible observations still need a
            # branch in the plan: they take the best alpha at the prediction
            fallback = int(np.argmax(self.alphas[:, pnz] @ predicted[pnz]))
            best = np.full(n_obs, fallback)
            possible = np.flatnonzero(p > 0)
            if len(possible):
                best[possible] = np.argmax(post[np.ix_(possible, pnz)] @ self.alphas[:, pnz].T,
                                           axis=1)
            for o in range(n_obs):
                g += self.m.Z[a, :, o] * self.alphas[best[o]]
            alpha = self.m.R[:, a] + self.gamma * (self.m.T[a] @ g)
            value = float(alpha[support] @ belief[support])
            if value > best_value:
                best_value, best_alpha, best_action = value, alpha, a
        if best_value > self.lower(belief) + 1e-9:
            self._add_alpha(best_alpha, best_action)
            self.report.backups += 1
            self._new_alphas += 1
            if self._new_alphas >= self.prune_every:
                self._prune()

    def _backup_upper(self, belief: np.ndarray, kids) -> None:
        q, _ = self._q_upper(belief, kids)
        value = float(q.max())
        if value < self.upper(belief) - 1e-9:
            self.points.add(belief, value - float(self.corner @ belief))

    def _prune(self) -> None:
        """Keep the alpha-vectors that are best at some visited belief (and the blind ones)."""
        self._new_alphas = 0
        if not self.visited:
            return
        S = self.m.shape[0]
        rows = np.concatenate([np.full(len(sup), i) for i, (sup, _) in enumerate(self.visited)])
        B = sp.csr_matrix((np.concatenate([p for _, p in self.visited]),
                           (rows, np.concatenate([sup for sup, _ in self.visited]))),
                          shape=(len(self.visited), S))
        best = np.asarray((B @ self.alphas.T).argmax(axis=1)).ravel()
        keep = set(best.tolist()) | set(range(self.m.shape[1]))
        index = np.array(sorted(keep))
        kept_alphas, kept_actions = self.alphas[index].copy(), self.alpha_actions[index].copy()
        self._alpha_count = len(index)
        self._alpha_buffer[:len(index)] = kept_alphas
        self._action_buffer[:len(index)] = kept_actions

    # -- search
    def _explore(self, belief: np.ndarray, epsilon: float, depth: int) -> None:
        gap = self.upper(belief) - self.lower(belief)
        if gap <= epsilon * self.gamma ** (-depth) or depth >= self.max_depth:
            return
        if len(self.visited) < 5000:
            support = np.flatnonzero(belief)
            self.visited.append((support, belief[support]))
        kids = self._expand(belief)
        q, ups_all = self._q_upper(belief, kids)
        a = int(np.argmax(q))
        _, p, post = kids[a]
        ups = ups_all[a]
        target = epsilon * self.gamma ** (-(depth + 1))
        scores = np.full(len(p), -np.inf)
        possible = p > 0
        cols = np.flatnonzero(post[possible].any(axis=0))
        lows = (post[np.ix_(possible, cols)] @ self.alphas[:, cols].T).max(axis=1)
        scores[possible] = p[possible] * (ups[possible] - lows - target)
        o = int(np.argmax(scores))
        self._explore(post[o], epsilon, depth + 1)
        self._backup_lower(belief, kids)
        self._backup_upper(belief, kids)

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
            self._explore(roots[k], self.gap_fraction * gaps[k], 0)
            if time.perf_counter() - last >= report_every:
                record(*bounds())
                last = time.perf_counter()
        record(*bounds())
        self.report.alpha_count = len(self.alphas)
        self.report.upper_points = len(self.points)
        return AlphaVectorPolicy(self.alphas.copy(), self.alpha_actions.copy(),
                                 self.m.actions)


class _UpperPoints:
    """Belief-value points of the upper bound, stored flat for the sawtooth:
    ``correction(b) = min(0, min_i excess_i * min_{s in supp b_i} b(s) / b_i(s))``.

    Only points whose support lies inside the belief's support can lower the bound (any
    other has a ratio of 0). Points are kept sorted by their smallest state index, so the
    candidates for a belief are a contiguous run found by binary search; structured
    models (RockSample, Tag: the robot's position is known, beliefs live in one block of
    states) then touch a small fraction of the points.
    """

    def __init__(self):
        self._support: list[np.ndarray] = []
        self._probs: list[np.ndarray] = []
        self._excess: list[float] = []
        self._flat = None

    def __len__(self) -> int:
        return len(self._excess)

    def add(self, belief: np.ndarray, excess: float) -> None:
        support = np.flatnonzero(belief)
        self._support.append(support)
        self._probs.append(belief[support].copy())
        self._excess.append(excess)
        self._flat = None

    def _build(self):
        lo = np.array([sup[0] for sup in self._support])
        order = np.argsort(lo, kind="stable")
        lengths = np.array([len(self._support[i]) for i in order])
        starts = np.concatenate([[0], np.cumsum(lengths)])
        self._flat = (np.concatenate([self._support[i] for i in order]),
                      np.concatenate([self._probs[i] for i in order]), starts, lo[order],
                      np.array([self._support[i][-1] for i in order]),
                      np.array([self._excess[i] for i in order]))

    def correction(self, beliefs: np.ndarray,
                   span: tuple[int, int] | None = None) -> np.ndarray:
        """(K,) sawtooth corrections (<= 0) for (K, S) beliefs. ``span`` bounds their
        supports (a superset is fine: points reaching outside a belief's own support get a
        ratio of 0 and change nothing)."""
        out = np.zeros(len(beliefs))
        if not self._excess:
            return out
        if self._flat is None:
            self._build()
        support, probs, starts, lo, hi, excess = self._flat
        for k, belief in enumerate(beliefs):
            if span is None:
                nz = np.flatnonzero(belief)
                if len(nz) == 0:
                    continue
                begin, end = nz[0], nz[-1]
            else:
                begin, end = span
            first = int(np.searchsorted(lo, begin, side="left"))
            last = int(np.searchsorted(lo, end, side="right"))
            if first >= last:
                continue
            inside = np.flatnonzero(hi[first:last] <= end) + first
            if len(inside) == 0:
                continue
            a, b = starts[first], starts[last]
            ratios = np.minimum.reduceat(belief[support[a:b]] / probs[a:b],
                                         starts[first:last] - a)
            best = (ratios[inside - first] * excess[inside]).min()
            out[k] = min(0.0, best)
        return out
