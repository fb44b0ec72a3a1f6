"""Compiled rollouts of the generative models (:mod:`planning.pomdp.generative`).

DESPOT's lower bound rolls the default policy out from every new node's scenarios to the
search depth; in numpy each depth costs one interpreter round trip per batch, which for
deep, never-ending problems (Tiger: 90 steps) dominated the search (measured: 93 % of a
1-s decision). These kernels run a whole rollout per scenario in one compiled loop,
reading each scenario's own uniforms, so they are the same returns as the numpy loop.
The tabular model's kernels of the compiled DESPOT (``tabular_step``, ``tabular_upper``,
``tabular_rollout``, ``tabular_qmdp_rollout``; see
:func:`planning.pomdp.despot_kernels.make_core`) are here too, all drawing successors with
:func:`successor`.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit
def successor(indptr, indices, cumulative, s, u):  # pragma: no cover (compiled)
    """The successor of state ``s`` drawn with the uniform ``u`` by inverse CDF over its CSR
    row (``indptr``, ``indices``; ``cumulative``: the running sum of the data), clipped to
    the row's last entry against rounding: the same draw as
    :meth:`~planning.pomdp.generative.TabularGenerative.step`."""
    start, stop = indptr[s], indptr[s + 1]
    base = cumulative[start - 1] if start > 0 else 0.0
    target = base + u * (cumulative[stop - 1] - base)
    k = start
    while k < stop - 1 and cumulative[k] <= target:
        k += 1
    return indices[k]


@numba.njit(cache=True)
def tabular_blind_rollout(states, scenarios, depths, uniforms, max_depth, discount, action,
                          indptr, indices, cumulative, R, terminal):  # pragma: no cover
    """(M,) discounted returns of repeating ``action`` from each row's state (M,) at its
    depth (M,) to ``max_depth``, successors by inverse CDF over the CSR row of ``T[action]``
    (``cumulative``: the running sum of its data) with ``uniforms[scenario, depth, 0]``."""
    out = np.zeros(len(states))
    for i in range(len(states)):
        s = states[i]
        value, scale = 0.0, 1.0
        for t in range(depths[i], max_depth):
            if terminal[s]:
                break
            value += scale * R[s, action]
            s = successor(indptr, indices, cumulative, s, uniforms[scenarios[i], t, 0])
            scale *= discount
        out[i] = value
    return out


@numba.njit
def tabular_step(params, state, action, u, out):  # pragma: no cover (compiled)
    """One scenario of :class:`~planning.pomdp.generative.TabularGenerative` (the kernel
    of the compiled DESPOT; see :func:`planning.pomdp.despot_kernels.make_core`)."""
    indptr, indices, cumulative, cum_z, R, terminal, values, blind, Q = params
    s = int(state[0])
    if terminal[s]:
        out[0] = s
        return 0.0, 0, True
    nxt = successor(indptr[action], indices[action], cumulative[action], s, u[0])
    o = 0
    while o < cum_z.shape[2] - 1 and u[1] >= cum_z[action, nxt, o]:
        o += 1
    out[0] = nxt
    return R[s, action], o, terminal[nxt]


@numba.njit
def tabular_upper(params, state):  # pragma: no cover (compiled)
    return params[6][int(state[0])]


@numba.njit
def tabular_rollout(params, states, scenarios, terminal_rows, depth, uniforms, max_depth,
                    discount):  # pragma: no cover (compiled)
    """The blind policy's returns over one node's scenarios, summed."""
    indptr, indices, cumulative, cum_z, R, terminal, values, blind, Q = params
    total = 0.0
    for i in range(len(states)):
        if terminal_rows[i]:
            continue
        s = int(states[i, 0])
        scale = 1.0
        for t in range(depth, max_depth):
            if terminal[s]:
                break
            total += scale * R[s, blind]
            s = successor(indptr[blind], indices[blind], cumulative[blind], s,
                          uniforms[scenarios[i], t, 0])
            scale *= discount
    return total


@numba.njit
def _qmdp_rollout_rows(states, scenarios, terminal_rows, depth, uniforms, max_depth,
                       discount, indptr, indices, cumulative, R, terminal, Q, out):
    """One node's rows under the node-level QMDP policy: at each depth every live row
    takes the action of largest summed Q over the node's live rows (Q is the MDP's (S, A));
    returns into ``out`` (n,)."""  # pragma: no cover (compiled)
    n = len(states)
    s = np.empty(n, dtype=np.int64)
    alive = np.empty(n, dtype=np.bool_)
    scale = np.ones(n)
    for i in range(n):
        s[i] = int(states[i, 0])
        alive[i] = not terminal_rows[i] and not terminal[s[i]]
        out[i] = 0.0
    actions = Q.shape[1]
    totals = np.empty(actions)
    for t in range(depth, max_depth):
        totals[:] = 0.0
        live = 0
        for i in range(n):
            if alive[i]:
                live += 1
                for a in range(actions):
                    totals[a] += Q[s[i], a]
        if live == 0:
            break
        a = int(np.argmax(totals))
        for i in range(n):
            if not alive[i]:
                continue
            out[i] += scale[i] * R[s[i], a]
            s[i] = successor(indptr[a], indices[a], cumulative[a], s[i],
                             uniforms[scenarios[i], t, 0])
            scale[i] *= discount
            if terminal[s[i]]:
                alive[i] = False


@numba.njit
def tabular_qmdp_rollouts(states, scenarios, depths, offsets, uniforms, max_depth, discount,
                          indptr, indices, cumulative, R, terminal, Q):  # pragma: no cover
    """(M,) returns of the node-level QMDP policy for each node
    ``offsets[j]:offsets[j + 1]`` (see :func:`_qmdp_rollout_rows`)."""
    out = np.zeros(len(states))
    no_terminal = np.zeros(len(states), dtype=np.bool_)
    for j in range(len(offsets) - 1):
        lo, hi = offsets[j], offsets[j + 1]
        _qmdp_rollout_rows(states[lo:hi], scenarios[lo:hi], no_terminal[lo:hi], depths[lo],
                           uniforms, max_depth, discount, indptr, indices, cumulative, R,
                           terminal, Q, out[lo:hi])
    return out


@numba.njit
def tabular_qmdp_rollout(params, states, scenarios, terminal_rows, depth, uniforms,
                         max_depth, discount):  # pragma: no cover (compiled)
    """The node-level QMDP policy's returns over one node's scenarios, summed."""
    indptr, indices, cumulative, cum_z, R, terminal, values, blind, Q = params
    out = np.empty(len(states))
    _qmdp_rollout_rows(states, scenarios, terminal_rows, depth, uniforms, max_depth,
                       discount, indptr, indices, cumulative, R, terminal, Q, out)
    return out.sum()
