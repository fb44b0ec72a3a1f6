"""The discrete Lat-POMDP compiled: the Lift-QMDP (or Lift-SARSOP) rollout (DESPOT's lower
bound, thesis sec. 7.2.3), resumable around the lattice's lazy evaluation, and the kernels
of the compiled DESPOT (:func:`planning.pomdp.despot_kernels.make_core`): ``lat_step``,
``lat_upper``, ``lat_rollout``.

In numpy each depth of a rollout is an interpreter round trip per batch; at DESPOT's depth
90 that cost 28 ms an expansion (measured: 97 % of a decision). :func:`lift_rollouts` runs
every node's rollout in one compiled loop. What it cannot do is evaluate the lattice
(Drake): when a node needs an edge or a point's contact row that is not known yet, the
kernel parks that node (its rows' points, cells, depths, scales and returns so far stay in
the arrays it was given) and reports the request in ``pending``; the caller evaluates every
request in one batch and calls it again, and parked nodes resume where they stopped.

With the rollouts compiled, the Python search itself was most of a Lat-DESPOT decision
(measured on ``cul_de_sac``: 1.3 ms an expansion, 270 ms a 30-trial decision), so the
search runs compiled too. Its kernels cannot park: when one needs an unknown edge or
contact row it writes the request (point, action; action -1 for a contact row) into the
parameters' ``request`` and returns a negative observation (``lat_step``) or NaN
(``lat_rollout``); the compiled core undoes the expansion, the model evaluates the request
(:meth:`planning.lattice.pomdp.LatticePOMDP.answer_kernel_request`) and the trial runs
again. Their parameters (:meth:`~planning.lattice.pomdp.LatticePOMDP.kernels`): ``(tabular,
status, neighbours, contact, upper_values, alphas_t, alpha_actions, asked, request,
bad_return)``, ``tabular`` being the Rel-POMDP's
(:func:`planning.pomdp.generative_kernels.tabular_step`'s).
"""

from __future__ import annotations

import numba
import numpy as np

from planning.pomdp.generative_kernels import successor, tabular_step

UNKNOWN, FEASIBLE = -1, 1
BAD = -1
"""The lattice point of ``s_bad``."""


@numba.njit(cache=True)
def lift_rollouts(points, cells, depth, scale, value, alive, offsets, scenarios, uniforms,
                  max_depth, discount, bad_return, indptr, indices, cumulative, R, terminal,
                  alphas_t, alpha_actions, status, neighbours, contact,
                  pending):  # pragma: no cover (compiled)
    """Advance every node's rollout until it ends or needs the lattice.

    Args:
        points, cells: (M,) int64 each row's lattice point (-1: s_bad) and cell.
        depth, scale, value: (M,) each row's depth, gamma^(steps so far) and return so far.
        alive: (M,) bool, rows still rolling out.
        offsets: (J + 1,) rows ``offsets[j]:offsets[j + 1]`` are node j's.
        scenarios, uniforms: each row's scenario and the (K, D + 1, U) uniforms.
        indptr, indices, cumulative, R, terminal: the discrete Rel-POMDP (per-action CSR
            rows of T, rewards (S, A), terminal (S,)).
        alphas_t: (S, N) the N vectors as columns (a cell's values contiguous) and
            alpha_actions: (N,) their actions: the lifted policy acts on the node's live
            rows' histogram b, an action's value being its best vector's ``alpha . b``
            (-inf without one). Rel-QMDP is ``Q`` with actions ``0 .. A - 1`` (the summed
            Q); Rel-SARSOP its alpha-vectors, transposed.
        status: (P, A) int8 the lattice's edges (-1 unknown, 0 infeasible, 1 feasible).
        neighbours: (P, A) each point's successor under each template.
        contact: (P, S) int8 un-modelled contact of each cell at each point (-1 unknown).
        pending: (J, 2) out: node j's request (point, action), action -1 for a point's
            contact row; point -1 when node j is done.
    """
    actions = status.shape[1]
    totals = np.empty(actions)
    vectors = alphas_t.shape[1]
    dots = np.empty(vectors)
    used = np.empty(actions, dtype=np.bool_)
    # the histogram of the live rows' cells: its support in ``support[:n_cells]``, so that
    # ``alpha . b`` costs a vector per distinct cell rather than per row
    histogram = np.zeros(len(alphas_t), dtype=np.int64)
    support = np.empty(len(alphas_t), dtype=np.int64)
    for j in range(len(offsets) - 1):
        lo, hi = offsets[j], offsets[j + 1]
        pending[j, 0], pending[j, 1] = -1, -1
        while True:
            first = -1
            n_cells = 0
            for i in range(lo, hi):
                if alive[i]:
                    if first < 0:
                        first = i
                    if histogram[cells[i]] == 0:
                        support[n_cells] = cells[i]
                        n_cells += 1
                    histogram[cells[i]] += 1
            if first < 0:
                break
            dots[:] = 0.0
            for m in range(n_cells):
                c = support[m]
                weight = float(histogram[c])
                histogram[c] = 0
                for k in range(vectors):
                    dots[k] += weight * alphas_t[c, k]
            totals[:] = -np.inf
            for k in range(vectors):
                totals[alpha_actions[k]] = max(totals[alpha_actions[k]], dots[k])
            point = points[first]
            used[:] = False
            chosen, parked = -1, False
            for _ in range(actions):  # Lift: the best feasible, asked in order of value
                best = -1
                for a in range(actions):
                    if not used[a] and (best < 0 or totals[a] > totals[best]):
                        best = a
                used[best] = True
                known = status[point, best]
                if known == UNKNOWN:
                    pending[j, 0], pending[j, 1] = point, best
                    parked = True
                    break
                if known == FEASIBLE:
                    chosen = best
                    break
            if parked:
                break
            if chosen < 0:  # nothing feasible: every live row goes to s_bad
                for i in range(lo, hi):
                    if alive[i]:
                        value[i] += scale[i] * bad_return
                        points[i], alive[i] = -1, False
                break
            target = neighbours[point, chosen]
            if contact[target, 0] == UNKNOWN:
                pending[j, 0], pending[j, 1] = target, -1
                break
            for i in range(lo, hi):
                if not alive[i]:
                    continue
                s = cells[i]
                nxt = successor(indptr[chosen], indices[chosen], cumulative[chosen], s,
                                uniforms[scenarios[i], depth[i], 0])
                touched = contact[target, nxt] == 1
                value[i] += scale[i] * (bad_return if touched else R[s, chosen])
                cells[i] = nxt
                points[i] = -1 if touched else target
                scale[i] *= discount
                depth[i] += 1
                alive[i] = not touched and not terminal[nxt] and depth[i] < max_depth


@numba.njit
def lat_step(params, state, action, u, out):  # pragma: no cover (compiled)
    """One scenario of the discrete Lat-POMDP (:meth:`planning.lattice.pomdp.LatticePOMDP.
    step`): ``state`` (2,) = (point, cell) into ``out`` (2,); returns (reward, observation,
    terminal), the observation -1 with ``request`` set when the edge, or the target's
    contact row, is not evaluated yet. Marks the edge asked, as the lattice's ``feasible``
    does."""
    (tabular, status, neighbours, contact, upper_values, alphas_t, alpha_actions, asked,
     request, bad_return) = params
    point = int(state[0])
    known = status[point, action]
    asked[point, action] = True
    if known == UNKNOWN:
        request[0], request[1] = point, action
        return 0.0, -1, False
    target = neighbours[point, action]
    if known == FEASIBLE and contact[target, 0] == UNKNOWN:
        request[0], request[1] = target, -1
        return 0.0, -1, False
    reward, observation, ended = tabular_step(tabular, state[1:], action, u, out[1:])
    if known != FEASIBLE or contact[target, int(out[1])] == 1:
        out[0], out[1] = BAD, state[1]
        return bad_return, observation, True
    out[0] = target
    return reward, observation, ended


@numba.njit
def lat_upper(params, state):  # pragma: no cover (compiled)
    """The upper bound of a live state: its cell's value (0 in ``s_bad``)."""
    return 0.0 if int(state[0]) == BAD else params[4][int(state[1])]


@numba.njit
def lat_rollout(params, states, scenarios, terminal_rows, depth, uniforms, max_depth,
                discount):  # pragma: no cover (compiled)
    """The lifted policy's returns over one node's scenarios (n, 2), summed
    (:func:`lift_rollouts`); NaN with ``request`` set when it needs the lattice."""
    (tabular, status, neighbours, contact, upper_values, alphas_t, alpha_actions, asked,
     request, bad_return) = params
    indptr, indices, cumulative, R, terminal = (tabular[0], tabular[1], tabular[2],
                                                tabular[4], tabular[5])
    n = len(states)
    points = np.empty(n, dtype=np.int64)
    cells = np.empty(n, dtype=np.int64)
    alive = np.empty(n, dtype=np.bool_)
    for i in range(n):
        points[i], cells[i] = int(states[i, 0]), int(states[i, 1])
        alive[i] = (not terminal_rows[i] and points[i] != BAD and depth < max_depth
                    and not terminal[cells[i]])
    depths = np.full(n, depth, dtype=np.int64)
    scale, value = np.ones(n), np.zeros(n)
    offsets = np.array([0, n], dtype=np.int64)
    pending = np.empty((1, 2), dtype=np.int64)
    lift_rollouts(points, cells, depths, scale, value, alive, offsets, scenarios, uniforms,
                  max_depth, discount, bad_return, indptr, indices, cumulative, R, terminal,
                  alphas_t, alpha_actions, status, neighbours, contact, pending)
    if pending[0, 0] >= 0:
        request[0], request[1] = pending[0, 0], pending[0, 1]
        return np.nan
    total = 0.0
    for i in range(n):
        if not terminal_rows[i]:
            total += value[i]
    return total
