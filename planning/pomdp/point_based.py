"""A point-based POMDP solver of the SARSOP family: heuristic search for value iteration
(HSVI2, Smith and Simmons 2005) with SARSOP's sampling (Kurniawati, Hsu and Lee 2008),
anytime, with both value bounds.

- Lower bound: alpha-vectors, started from the blind policies (one fixed action for
  ever) and improved by point-based backups at the beliefs the search visits.
- Upper bound: the fast informed bound (FIB, Hauskrecht 2000) at the belief simplex's
  corners, refined by belief-value points and read with the sawtooth interpolation.
- Search: from the initial belief, follow the action with the best upper bound and the
  observation with the largest weighted excess gap, ``p(o | b, a) (gap(b') - eps / g^t)``;
  back up both bounds on the way back. The target ``eps`` follows the root gap (a fraction
  of it), so the solver stays anytime. Where a trial stops is the ``trial_rule``:

  - ``"sarsop"`` (default): SARSOP's selective deep sampling (the SAMPLE procedure). Each
    node carries the lower target ``L`` (what its value must reach to raise the root's
    lower bound) and ``U``; a trial goes on while the node's upper bound says improving it
    can still pay (``V_up > L``, or above ``max(U, V_low + eps / g^t)``), and stops once
    its gap is below ``kappa eps / g^t``. SARSOP's value prediction by binning is left
    out (the prediction is the upper bound).
  - ``"hsvi"``: HSVI2's rule, stop when the gap is below ``eps / g^t``. Trials are
    shallower and the lower bound tends to rise later (RockSample(7,8) at 10 s, three runs
    with ``gap_fraction`` 0.48, 0.5, 0.52: 20.72, 20.93, 20.59 with it; 20.73, 21.13,
    21.04 with the SARSOP rule; ``cmanip bench pomdp --trial-rule``).
- Pruning: every ``prune_every`` new vectors, the alpha-vectors that are best at none of
  the beliefs the search has visited (and are not blind policies) are dropped. Each vector
  remembers its plan: the vector each observation leads to. With ``keep_subplans``,
  pruning keeps those too, so acting greedily on the vectors is sure to earn the lower
  bound; it is off by default because it keeps about 1.5 times the vectors, and the
  policy earned its bound without it (RockSample(7,8) after 60 s: bound 21.38, policy
  21.53 +- 0.85 over 200 simulated episodes). Pruning against only the most recent
  beliefs, tried for speed, did not: with a window of 5000, the policy simulated 1.3
  below its bound after 300 s.

Inside the search a belief is its support and the probabilities there; predictions gather
only the rows of T in the support, and only the chosen action's alpha-vector is built over
all states. That is what keeps RockSample(7,8) (12,545 states, beliefs over at most 256)
tractable. The per-node loops (expansion, the backup's choice, the new alpha, the sawtooth)
are compiled (:mod:`planning.pomdp.point_based_kernels`): in numpy their many small calls cost
more than their arithmetic. The backup's choice and the children's upper bounds loop over
actions on numba's threads (``NUMBA_NUM_THREADS``; both cores here). The alpha-vectors are
kept in two memory layouts (:mod:`planning.pomdp.alpha_store`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from planning.pomdp.alpha_store import AlphaStore
from planning.pomdp.point_based_kernels import (
    alpha_products,
    best_backup,
    chain_point,
    child_uppers,
    expand,
    new_alpha,
    products_at_beliefs,
    sawtooth_corrections,
)
from planning.pomdp.qmdp import solve_mdp
from planning.pomdp.tabular import TabularPOMDP


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
    nodes: int = 0  # beliefs expanded by the search
    backups: int = 0
    alpha_count: int = 0
    upper_points: int = 0

    def at(self, seconds: float) -> tuple[float, float]:
        """(lower, upper) as they stood at ``seconds`` (the last row not after it)."""
        rows = [r for r in self.history if r[0] <= seconds]
        row = rows[-1] if rows else self.history[0]
        return row[1], row[2]


class PointBasedSolver:
    """HSVI2/SARSOP-style solver (see the module docstring).

    Args:
        pomdp: the model.
        gap_fraction: each trial's target precision, as a fraction of the root gap.
        max_depth: deepest belief a trial visits.
        prune_every: prune the alpha-vectors after this many new ones.
        trial_rule: where a trial stops, ``"sarsop"`` or ``"hsvi"`` (module docstring).
        kappa: the SARSOP rule's gap floor, as a fraction of the node's target precision.
        keep_subplans: pruning also keeps every vector a kept vector's plan leads to, so
            that acting greedily on the vectors is sure to earn the lower bound (module
            docstring).
    """

    TRIAL_RULES = ("sarsop", "hsvi")

    def __init__(self, pomdp: TabularPOMDP, *, gap_fraction: float = 0.5,
                 max_depth: int = 250, prune_every: int = 200, trial_rule: str = "sarsop",
                 kappa: float = 0.5, keep_subplans: bool = False):
        if trial_rule not in self.TRIAL_RULES:
            raise ValueError(f"trial_rule must be one of {self.TRIAL_RULES}, not {trial_rule!r}")
        if not 0.0 < kappa <= 1.0:
            raise ValueError(f"kappa must be in (0, 1], not {kappa}")
        if prune_every < 1:
            raise ValueError(f"prune_every must be >= 1, not {prune_every}")
        self.m = pomdp
        S, A, n_obs = pomdp.shape
        self.gamma = pomdp.discount
        self.gap_fraction = gap_fraction
        self.max_depth = max_depth
        self.prune_every = prune_every
        self.trial_rule = trial_rule
        self.kappa = kappa
        self.keep_subplans = keep_subplans
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
        self._scratch_per_action = np.zeros((A, S))  # the same, one per thread's action
        self._accumulator = np.zeros(S)  # the same for the predictions of _expand
        self._touched = np.zeros(S, dtype=np.bool_)
        self.TZ = [[sp.csr_matrix(pomdp.T[a].multiply(pomdp.Z[a, :, o][None, :]))
                    for o in range(n_obs)] for a in range(A)]
        blind, blind_actions = self._blind_policies()
        # room for 1024 vectors (two layouts, 16 KB per vector and 1000 states), at most
        # 512 MB to start with
        self.store = AlphaStore(S, n_obs,
                                capacity=int(np.clip(2**25 // S, 4 * len(blind), 1024)))
        for k, (alpha, action) in enumerate(zip(blind, blind_actions, strict=True)):
            self.store.add(alpha, action, np.full(n_obs, k))  # the same action for ever
        self.store.written()
        self.corner = self._fast_informed_bound().max(axis=1)
        self.points = _UpperPoints(S)
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
        return self.store.vectors

    @property
    def alpha_actions(self) -> np.ndarray:
        """(K,) the action of each alpha-vector (a view)."""
        return self.store.actions

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
        return alpha_products(self.store.view(), 0, columns, np.ascontiguousarray(rows))

    def _upper_local(self, support: np.ndarray, beliefs: np.ndarray) -> np.ndarray:
        """(K,) upper bounds of (K, m) beliefs that share the ``support`` (m,)."""
        return beliefs @ self.corner[support] + self.points.correction(support, beliefs,
                                                                       self._scratch)

    def _expand(self, support: np.ndarray, probs: np.ndarray) -> _Expansion:
        """Predictions and posteriors for every action (see :class:`_Expansion`); they
        gather only the rows of T in the support."""
        return _Expansion(*expand(self._T_indptr, self._T_indices, self._T_data, self._Z,
                                  support, probs, self._accumulator, self._touched),
                          rewards=probs @ self.m.R[support])

    def _child_uppers(self, kids: _Expansion, actions: range | list[int]) -> np.ndarray:
        """(A, O) upper bounds of the possible children of ``actions`` (0 elsewhere)."""
        pts = self.points
        return child_uppers(kids.offsets, kids.states, kids.post, kids.p,
                            np.asarray(actions, dtype=np.int64), self.corner, pts.head,
                            pts.next, pts.starts, pts.largest, pts.excess, pts.states,
                            pts.probs, self._scratch_per_action)

    def _q_upper(self, kids: _Expansion, ups: np.ndarray,
                 actions: range | list[int] | None = None) -> np.ndarray:
        """(A,) upper-bound Q(b, a) from the children's upper bounds ``ups`` (A, O); only
        for ``actions`` (default: all; the others are left at +inf)."""
        q = np.full(kids.actions, np.inf)
        for a in range(kids.actions) if actions is None else actions:
            q[a] = kids.rewards[a] + self.gamma * kids.p[a] @ ups[a]
        return q

    # -- backups
    def _backup_lower(self, support, probs, kids) -> None:
        """Point-based backup: the value of every action is computed on the supports; only
        the best action's alpha-vector is built over all states."""
        best_value, best_action, best_choice = best_backup(
            self.store.view(), kids.offsets, kids.states, kids.predicted, kids.p, kids.post,
            kids.rewards, self.gamma)
        if best_value <= self._lower_local(support, probs) + 1e-9:
            return
        row = self.store.reserve(best_action, best_choice)
        new_alpha(self.store.by_row, row, best_choice, best_action, self._T_indptr,
                  self._T_indices, self._T_data, self._Z, self._R, self.gamma)
        self.store.written()
        self.report.backups += 1
        self._new_alphas += 1
        if self._new_alphas >= self.prune_every:
            self._prune()

    def _backup_upper(self, support, probs, kids, q: np.ndarray, explored: int) -> None:
        """Back up the upper bound. Only the explored action's Q is recomputed: the others'
        children did not change, and an upper bound computed earlier stays an upper bound
        (the bound only tightens)."""
        q = q.copy()
        ups = self._child_uppers(kids, [explored])
        q[explored] = self._q_upper(kids, ups, [explored])[explored]
        value = float(q.max())
        if value < float(self._upper_local(support, probs[None, :])[0]) - 1e-9:
            self.points.add(support, probs, value - float(self.corner[support] @ probs))

    def _prune(self) -> None:
        """Keep the alpha-vectors that are best at some visited belief, the blind ones and,
        with ``keep_subplans``, every vector their plans lead to.

        Incremental: each visited belief keeps its best alpha-vector from the last pruning,
        so only the vectors added since are compared at the beliefs seen before, and only
        the beliefs visited since are compared with every vector. The result is that of
        comparing all beliefs with all vectors, at a fraction of the products."""
        self._new_alphas = 0
        if not self.visited:
            return
        A = self.m.shape[1]
        count, fresh_from = len(self.store), self._pruned_alphas
        seen = len(self._best_value)
        offsets = np.cumsum([0] + [len(sup) for sup, _ in self.visited])
        states = np.concatenate([sup for sup, _ in self.visited])
        probs = np.concatenate([p for _, p in self.visited])
        best_value = np.concatenate([self._best_value, np.full(len(self.visited) - seen,
                                                               -np.inf)])
        best_index = np.concatenate([self._best_index,
                                     np.zeros(len(self.visited) - seen, dtype=np.int64)])
        # the beliefs seen before against the new vectors, the new beliefs against all
        for beliefs, first in ((slice(0, seen), fresh_from),
                               (slice(seen, len(self.visited)), 0)):
            if first >= count or beliefs.start == beliefs.stop:
                continue
            values = products_at_beliefs(self.store.view(), first,
                                         offsets[beliefs.start:beliefs.stop + 1], states, probs)
            top = values.argmax(axis=1)
            top_value = values[np.arange(len(values)), top]
            better = top_value > best_value[beliefs]
            best_value[beliefs] = np.where(better, top_value, best_value[beliefs])
            best_index[beliefs] = np.where(better, first + top, best_index[beliefs])
        index = np.unique(np.concatenate([best_index, np.arange(A)]))
        if self.keep_subplans:
            index = self.store.closure(index)
        renumber = np.full(count, -1, dtype=np.int64)
        renumber[index] = np.arange(len(index))
        self.store.keep(index)
        self._best_value, self._best_index = best_value, renumber[best_index]
        self._pruned_alphas = len(index)

    # -- search
    def _explore(self, support: np.ndarray, probs: np.ndarray, epsilon: float,
                 depth: int, low_target: float = -np.inf,
                 up_target: float = -np.inf) -> None:
        """One trial from this belief down (recursive), then the backups on the way back.

        ``low_target`` and ``up_target`` are the SARSOP rule's ``L`` and ``U`` here
        (-inf at the root, where they become ``V_low`` and ``V_low + eps``)."""
        upper = float(self._upper_local(support, probs[None, :])[0])
        lower = self._lower_local(support, probs)
        precision = epsilon * self.gamma ** (-depth)
        if depth >= self.max_depth or self._trial_ends(upper, lower, precision, low_target,
                                                       up_target):
            return
        self.visited.append((support, probs))
        self.report.nodes += 1
        kids = self._expand(support, probs)
        all_ups = self._child_uppers(kids, range(kids.actions))
        q = self._q_upper(kids, all_ups)
        a = int(np.argmax(q))
        nz, _, p, post = kids.action(a)
        possible = np.flatnonzero(p > 0)
        ups = np.where(p > 0, all_ups[a], -np.inf)
        lows = np.full(len(p), -np.inf)
        lows[possible] = self._products(nz, post[possible]).max(axis=1)
        scores = np.full(len(p), -np.inf)
        scores[possible] = p[possible] * (ups[possible] - lows[possible]
                                          - precision / self.gamma)
        o = int(np.argmax(scores))
        if self.trial_rule == "sarsop":
            # SARSOP's L' = max(L, max_a Q_low(b, a)); with no belief tree we use V_low(b),
            # which is at most that (every alpha-vector is a backup), so trials run deeper
            reward = float(kids.rewards[a])
            low_target = _child_target(max(low_target, lower), reward, p, lows, o,
                                       self.gamma)
            up_target = _child_target(max(up_target, lower + precision), reward, p, ups, o,
                                      self.gamma)
        keep = post[o] > 0
        self._explore(nz[keep], post[o][keep], epsilon, depth + 1, low_target, up_target)
        self._backup_lower(support, probs, kids)
        self._backup_upper(support, probs, kids, q, a)

    def _trial_ends(self, upper: float, lower: float, precision: float, low_target: float,
                    up_target: float) -> bool:
        """Whether a trial stops at a belief with these bounds (module docstring);
        ``precision`` is ``eps / g^t`` at its depth."""
        if self.trial_rule == "hsvi":
            return upper - lower <= precision
        return (upper - lower <= self.kappa * precision
                or (upper <= low_target and upper <= max(up_target, lower + precision)))

    def solve(self, seconds: float, *, report_every: float = 1.0, callback=None,
              initial_beliefs: np.ndarray | None = None,
              weights: np.ndarray | None = None,
              max_trials: int | None = None) -> AlphaVectorPolicy:
        """Improve the bounds for ``seconds`` of wall time; return the lower-bound policy.

        Args:
            seconds: wall-time budget (s).
            report_every: how often (s) the bounds are recorded in :attr:`report`.
            callback: ``callback(elapsed, lower, upper, trials)``, called at every record
                (e.g. :class:`~planning.pomdp.progress.SolverProgressBar`).
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

        trials = 0

        def record(lows, ups):
            elapsed = time.perf_counter() - start
            lo, up = float(w @ lows), float(w @ ups)
            self.report.history.append((elapsed, lo, up))
            if callback is not None:
                callback(elapsed, lo, up, trials)

        record(*bounds())
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
    other has a ratio of 0), so a point's smallest state must be in the belief's support.
    Points are chained by their smallest state (``head[s]``, then ``next``), most negative
    excess first, and a belief reads only the chains of its own states, each until a point
    can no longer lower its bound; structured models (RockSample, Tag: the
    robot's position is known, beliefs live in one block of states) then touch a small
    fraction of the points. The storage is flat and grows by doubling, and the whole
    correction of a batch of beliefs is one compiled call (:func:`sawtooth_corrections`).
    """

    def __init__(self, n_states: int):
        self.head = np.full(n_states, -1, dtype=np.int64)
        self.next = np.empty(64, dtype=np.int64)
        self.starts = np.zeros(65, dtype=np.int64)  # point i owns entries starts[i]:[i + 1]
        self.largest = np.empty(64, dtype=np.int64)  # each point's largest state
        self.excess = np.empty(64)
        self.states = np.empty(1024, dtype=np.int64)
        self.probs = np.empty(1024)
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def add(self, support: np.ndarray, probs: np.ndarray, excess: float) -> None:
        i, begin = self._count, int(self.starts[self._count])
        if i == len(self.excess):
            self.next, self.largest, self.excess = (_doubled(a) for a in
                                                    (self.next, self.largest, self.excess))
            self.starts = np.concatenate([self.starts, np.zeros(len(self.excess) - i,
                                                                dtype=np.int64)])
        while begin + len(support) > len(self.states):
            self.states, self.probs = _doubled(self.states), _doubled(self.probs)
        self.states[begin:begin + len(support)] = support
        self.probs[begin:begin + len(support)] = probs
        self.starts[i + 1] = begin + len(support)
        self.largest[i], self.excess[i] = support[-1], excess
        chain_point(self.head, self.next, self.excess, int(support[0]), i)
        self._count += 1

    def correction(self, support: np.ndarray, beliefs: np.ndarray,
                   scratch: np.ndarray) -> np.ndarray:
        """(K,) sawtooth corrections (<= 0) for (K, m) beliefs on the sorted ``support``.

        ``scratch`` is an all-zero (S,) buffer, used to read a belief at a point's states;
        it is zero again on return.
        """
        if not self._count or len(support) == 0:
            return np.zeros(len(beliefs))
        return sawtooth_corrections(self.head, self.next, self.starts, self.largest,
                                    self.excess, self.states, self.probs, support,
                                    np.ascontiguousarray(beliefs), scratch)


def _doubled(array: np.ndarray) -> np.ndarray:
    grown = np.empty(2 * len(array), dtype=array.dtype)
    grown[:len(array)] = array
    return grown


@dataclass(frozen=True)
class _Expansion:
    """A belief's children, flat: action a owns entries ``offsets[a]:offsets[a + 1]`` of
    ``states`` (the prediction's support) and ``predicted`` (its probabilities), and those
    columns of ``post`` (O, total), the posteriors; ``p`` (A, O) are p(o | b, a);
    ``rewards`` (A,) are R(b, a)."""

    offsets: np.ndarray
    states: np.ndarray
    predicted: np.ndarray
    p: np.ndarray
    post: np.ndarray
    rewards: np.ndarray

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


def _child_target(target: float, reward: float, p: np.ndarray, values: np.ndarray, o: int,
                  gamma: float) -> float:
    """The value the child after observation ``o`` must reach for ``R(b, a) + g sum_o'
    p(o') v(o')`` to reach ``target``, the other children keeping their ``values`` (O,)
    (-inf where p is 0). SARSOP's propagation of L and U down a trial."""
    others = sum(float(p[k] * values[k]) for k in range(len(p)) if k != o and p[k] > 0)
    return (target - reward - gamma * others) / (gamma * float(p[o]))
