"""The DESPOT search compiled: the same trials, expansions and backups as
:class:`planning.pomdp.despot.Despot`, on a tree held in flat arrays.

Why: in Python every belief node costs a few dozen interpreter round trips (measured on
Tag and RockSample(7,8): 0.3-0.4 ms per expansion, about 100 trials per second), which
left the search two orders of magnitude short of the reference C++ DESPOT's trials. Here a
trial runs in one compiled call, for models that give compiled kernels
(``model.kernels()``: ``step``, ``upper`` and ``rollout`` functions and their parameter
tuple; see :func:`make_core`); Python keeps the clock between trials, so the wall-clock
budget is checked as often as before.

The tree: belief node b has ``depth``, its scenarios in the pool (``start``, ``count``:
scenario ids, states (float64, the models' integers exactly) and terminal flags), bounds
``l0, u0, lower, upper`` and, once expanded, its A action nodes from ``first_action``;
action node q has ``rho`` and its children in ``child_node[child_start : child_start +
child_count]`` (with their observation codes). Bounds and backups are those of the module
docstring of :mod:`planning.pomdp.despot`.
"""

from __future__ import annotations

import numba
import numpy as np

GROW = -1
"""Status of a trial that stopped for want of room (the caller grows the arrays)."""
NEED = -2
"""Status of a trial that stopped because a kernel needs data the model computes lazily
(the caller has the model answer its request and runs the trial again)."""


@numba.njit
def _group_by_code(codes):  # pragma: no cover (compiled)
    """A stable order of ``codes`` (non-negative ints) by value: a counting sort when the
    codes are few, else a merge sort."""
    n = len(codes)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    top = codes.max()
    if top > 4 * n + 64:
        return np.argsort(codes, kind="mergesort")
    counts = np.zeros(top + 2, dtype=np.int64)
    for i in range(n):
        counts[codes[i] + 1] += 1
    for c in range(1, top + 2):
        counts[c] += counts[c - 1]
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[counts[codes[i]]] = i
        counts[codes[i]] += 1
    return order


def make_core(step, upper, rollout):
    """The compiled ``trial(tree, ...)`` for one model's kernels.

    Kernel signatures (all ``numba.njit``):
        ``step(params, state (d,), action, u (U,), out (d,)) -> (reward, observation,
        terminal)``: one scenario, the next state written to ``out``;
        ``upper(params, state (d,)) -> float``: the upper bound of a non-terminal state;
        ``rollout(params, states (n, d), scenarios (n,), terminal (n,), depth, uniforms,
        max_depth, discount) -> float``: the sum over one node's scenarios of the default
        policy's discounted returns.

    A model whose kernels read data it computes lazily (the configuration lattice's edges)
    has ``step`` return a negative observation, or ``rollout`` NaN, when that data is not
    there yet (what is missing: the model's own business, written into its parameters).
    The expansion is then undone (the tree's counters and the node's actions restored,
    nothing reachable changed) and the trial returns :data:`NEED`, leaving in ``resume``
    where it stopped (its path length and root gap); the caller has the model compute what
    was asked and calls the trial again, which resumes at that node: the same trial as one
    that was never stopped (the same tree, whatever the model had computed before).

    Returns ``(trial, backup)``: ``backup`` backs up a path, for a search that ends while a
    trial is stopped.
    """

    @numba.njit
    def expand(b, params, tree, pool, counts, uniforms, actions, max_depth, discount, lam,
               k):  # pragma: no cover (compiled)
        (depth, start, count, l0, u0, lower, upper_b, first_action, q_rho, q_lower, q_upper,
         q_child_start, q_child_count, child_node, child_obs) = tree
        scen, states, term = pool
        d = states.shape[1]
        live = 0
        for i in range(start[b], start[b] + count[b]):
            if not term[i]:
                live += 1
        if (counts[0] + actions * live >= len(depth) or counts[1] + actions >= len(q_rho)
                or counts[2] + actions * live >= len(child_node)
                or counts[3] + actions * live >= len(scen)):
            return GROW
        saved = counts.copy()  # to undo an expansion a kernel cannot finish
        weight = discount ** depth[b] / k
        rows = np.empty(live, dtype=np.int64)
        j = 0
        for i in range(start[b], start[b] + count[b]):
            if not term[i]:
                rows[j] = i
                j += 1
        nxt = np.empty((live, d))
        obs = np.empty(live, dtype=np.int64)
        ends = np.empty(live, dtype=np.bool_)
        first_action[b] = counts[1]
        for a in range(actions):
            q = counts[1]
            counts[1] += 1
            reward_sum = 0.0
            for j in range(live):
                i = rows[j]
                r, o, t = step(params, states[i], a, uniforms[scen[i], depth[b]], nxt[j])
                if o < 0:
                    counts[:] = saved
                    first_action[b] = -1
                    return NEED
                reward_sum += r
                obs[j] = o
                ends[j] = t
            q_rho[q] = weight * reward_sum - lam
            q_child_start[q] = counts[2]
            q_child_count[q] = 0
            order = _group_by_code(obs)
            g = 0
            while g < live:
                h = g
                while h < live and obs[order[h]] == obs[order[g]]:
                    h += 1
                c = counts[0]
                counts[0] += 1
                p0 = counts[3]
                for m in range(g, h):
                    row = order[m]
                    scen[p0 + m - g] = scen[rows[row]]
                    states[p0 + m - g] = nxt[row]
                    term[p0 + m - g] = ends[row]
                counts[3] += h - g
                depth[c] = depth[b] + 1
                start[c] = p0
                count[c] = h - g
                first_action[c] = -1
                w = discount ** depth[c] / k
                value = rollout(params, states[p0:p0 + h - g], scen[p0:p0 + h - g],
                                term[p0:p0 + h - g], depth[c], uniforms, max_depth, discount)
                if value != value:
                    counts[:] = saved
                    first_action[b] = -1
                    return NEED
                bound = 0.0
                all_ended = True
                for m in range(p0, p0 + h - g):
                    if not term[m]:
                        bound += upper(params, states[m])
                        all_ended = False
                l0[c] = w * value - lam
                u0[c] = l0[c] if all_ended else max(w * bound, l0[c])
                lower[c] = l0[c]
                upper_b[c] = lower[c] if depth[c] >= max_depth else u0[c]
                child_node[counts[2]] = c
                child_obs[counts[2]] = obs[order[g]]
                counts[2] += 1
                q_child_count[q] += 1
                g = h
            low, up = q_rho[q], q_rho[q]
            for m in range(q_child_start[q], q_child_start[q] + q_child_count[q]):
                low += lower[child_node[m]]
                up += upper_b[child_node[m]]
            q_lower[q], q_upper[q] = low, up
        return 0

    @numba.njit
    def backup(path, length, tree, actions, max_depth, crossings):  # pragma: no cover
        (depth, start, count, l0, u0, lower, upper_b, first_action, q_rho, q_lower, q_upper,
         q_child_start, q_child_count, child_node, child_obs) = tree
        for p in range(length - 1, -1, -1):
            b = path[p]
            if first_action[b] >= 0:
                best_low, best_up = l0[b], l0[b]
                for q in range(first_action[b], first_action[b] + actions):
                    low, up = q_rho[q], q_rho[q]
                    for m in range(q_child_start[q], q_child_start[q] + q_child_count[q]):
                        low += lower[child_node[m]]
                        up += upper_b[child_node[m]]
                    q_lower[q], q_upper[q] = low, up
                    best_low = max(best_low, low)
                    best_up = max(best_up, up)
                lower[b] = best_low
                if depth[b] < max_depth:
                    upper_b[b] = best_up
            if upper_b[b] < lower[b]:
                if lower[b] - upper_b[b] > 1e-9:
                    crossings[0] += 1
                upper_b[b] = lower[b]

    @numba.njit
    def trial(root, tree, pool, counts, uniforms, params, actions, max_depth, discount, lam,
              k, xi, crossings, path, resume):  # pragma: no cover (compiled)
        """One AR-DESPOT trial and its backup; returns the path length (GROW if the
        arrays ran out of room before an expansion: the path so far is backed up). NEED
        if a kernel asked for lazily computed data: nothing backed up, ``resume`` (2,)
        holds the path's length and the trial's root gap, and the next call resumes the
        trial at the path's last node (``resume[0]`` 0: a new trial)."""
        (depth, start, count, l0, u0, lower, upper_b, first_action, q_rho, q_lower, q_upper,
         q_child_start, q_child_count, child_node, child_obs) = tree
        term = pool[2]
        if resume[0] > 0:
            length, gap = int(resume[0]), resume[1]
            node = path[length - 1]
            resume[0] = 0.0
        else:
            gap = upper_b[root] - lower[root]
            node = root
            path[0] = root
            length = 1
        status = 0
        while depth[node] < max_depth:
            ended = True
            for i in range(start[node], start[node] + count[node]):
                if not term[i]:
                    ended = False
                    break
            if ended:
                break
            if first_action[node] < 0:
                status = expand(node, params, tree, pool, counts, uniforms, actions,
                                max_depth, discount, lam, k)
                if status == NEED:
                    resume[0], resume[1] = length, gap
                    return NEED
                if status == GROW:
                    break
            best_q, best_up = -1, -np.inf
            for q in range(first_action[node], first_action[node] + actions):
                if q_upper[q] > best_up:
                    best_q, best_up = q, q_upper[q]
            if q_child_count[best_q] == 0:
                break
            best_c, best_e = -1, -np.inf
            for m in range(q_child_start[best_q], q_child_start[best_q] + q_child_count[best_q]):
                c = child_node[m]
                excess = upper_b[c] - lower[c] - xi * count[c] / k * gap
                if excess > best_e:
                    best_c, best_e = c, excess
            node = best_c
            path[length] = node
            length += 1
            if best_e < 0:
                break
        backup(path, length, tree, actions, max_depth, crossings)
        return GROW if status == GROW else length

    return trial, backup


class ArrayTree:
    """The flat arrays of one search's tree (see the module docstring), grown on demand."""

    def __init__(self, state_dim: int, actions: int, capacity: int = 4096):
        self.actions = actions
        self._allocate(state_dim, capacity)
        self.counts = np.zeros(4, dtype=np.int64)  # belief, action, child, pool entries

    def _allocate(self, d: int, capacity: int) -> None:
        b = q = capacity
        self.depth = np.empty(b, dtype=np.int64)
        self.start = np.empty(b, dtype=np.int64)
        self.count = np.empty(b, dtype=np.int64)
        self.l0, self.u0 = np.empty(b), np.empty(b)
        self.lower, self.upper = np.empty(b), np.empty(b)
        self.first_action = np.full(b, -1, dtype=np.int64)
        self.q_rho, self.q_lower, self.q_upper = np.empty(q), np.empty(q), np.empty(q)
        self.q_child_start = np.empty(q, dtype=np.int64)
        self.q_child_count = np.empty(q, dtype=np.int64)
        self.child_node = np.empty(b, dtype=np.int64)
        self.child_obs = np.empty(b, dtype=np.int64)
        self.scen = np.empty(4 * b, dtype=np.int64)
        self.states = np.empty((4 * b, d))
        self.term = np.empty(4 * b, dtype=np.bool_)

    def grow(self, needed: int) -> None:
        """At least double every array, and make room for ``needed`` more entries."""
        names = ("depth", "start", "count", "l0", "u0", "lower", "upper", "first_action",
                 "q_rho", "q_lower", "q_upper", "q_child_start", "q_child_count",
                 "child_node", "child_obs", "scen", "states", "term")
        for name in names:
            old = getattr(self, name)
            size = max(2 * len(old), len(old) + 4 * needed)
            new = np.empty((size, *old.shape[1:]), dtype=old.dtype)
            new[:len(old)] = old
            setattr(self, name, new)

    @property
    def nbytes(self) -> int:
        """The arrays' size (bytes)."""
        tree, pool = self.as_tuples()
        return sum(a.nbytes for a in (*tree, *pool))

    def as_tuples(self):
        """(tree, pool) as the kernels take them."""
        return ((self.depth, self.start, self.count, self.l0, self.u0, self.lower,
                 self.upper, self.first_action, self.q_rho, self.q_lower, self.q_upper,
                 self.q_child_start, self.q_child_count, self.child_node, self.child_obs),
                (self.scen, self.states, self.term))

    def action_range(self, b: int) -> range:
        first = int(self.first_action[b])
        return range(first, first + self.actions) if first >= 0 else range(0)
