"""The compiled Lift-QMDP (or Lift-SARSOP) rollout on the discrete Lat-POMDP (DESPOT's lower bound,
thesis sec. 7.2.3), resumable around the lattice's lazy evaluation.

In numpy each depth of a rollout is an interpreter round trip per batch; at DESPOT's depth
90 that cost 28 ms an expansion (measured: 97 % of a decision). This kernel runs every
node's rollout in one compiled loop. What it cannot do is evaluate the lattice (Drake):
when a node needs an edge or a point's contact row that is not known yet, the kernel parks
that node (its rows' points, cells, depths, scales and returns so far stay in the arrays
it was given) and reports the request in ``pending``; the caller evaluates every request
in one batch and calls it again, and parked nodes resume where they stopped.
"""

from __future__ import annotations

import numba
import numpy as np

from planning.pomdp.generative_kernels import successor

UNKNOWN, FEASIBLE = -1, 1


@numba.njit(cache=True)
def lift_rollouts(points, cells, depth, scale, value, alive, offsets, scenarios, uniforms,
                  max_depth, discount, bad_return, indptr, indices, cumulative, R, terminal,
                  alphas, alpha_actions, status, neighbours, contact,
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
        alphas, alpha_actions: (N, S) vectors and (N,) their actions: the lifted policy
            acts on the node's live rows' histogram b, an action's value being its best
            vector's ``alpha . b`` (-inf without one). Rel-QMDP is ``Q.T`` with actions
            ``0 .. A - 1`` (the summed Q); Rel-SARSOP its alpha-vectors.
        status: (P, A) int8 the lattice's edges (-1 unknown, 0 infeasible, 1 feasible).
        neighbours: (P, A) each point's successor under each template.
        contact: (P, S) int8 un-modelled contact of each cell at each point (-1 unknown).
        pending: (J, 2) out: node j's request (point, action), action -1 for a point's
            contact row; point -1 when node j is done.
    """
    actions = status.shape[1]
    totals = np.empty(actions)
    dots = np.empty(len(alphas))
    used = np.empty(actions, dtype=np.bool_)
    for j in range(len(offsets) - 1):
        lo, hi = offsets[j], offsets[j + 1]
        pending[j, 0], pending[j, 1] = -1, -1
        while True:
            first = -1
            dots[:] = 0.0
            for i in range(lo, hi):
                if alive[i]:
                    if first < 0:
                        first = i
                    for k in range(len(alphas)):
                        dots[k] += alphas[k, cells[i]]
            if first < 0:
                break
            totals[:] = -np.inf
            for k in range(len(alphas)):
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
