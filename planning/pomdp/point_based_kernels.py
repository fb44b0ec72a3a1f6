"""Compiled inner loops of the point-based solver (:mod:`planning.pomdp.point_based`).

Each runs once per belief node of the search, over that belief's support only; in numpy
the per-action calls cost more in interpreter overhead than in arithmetic.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def expand(indptr, indices, data, Z, support, probs, accumulator, touched):  # pragma: no cover
    """Predictions and posteriors of a belief for every action.

    Args:
        indptr: (A, S + 1) row starts of every T[a] in one CSR structure.
        indices, data: its columns and probabilities.
        Z: (A, S, O) observation probabilities.
        support, probs: the belief's sorted support (m,) and probabilities (m,).
        accumulator, touched: all-zero (S,) float and bool buffers, zero again on return.

    Returns:
        ``offsets`` (A + 1,): action a owns entries offsets[a]:offsets[a + 1] of
        ``states`` (the prediction's sorted support) and ``predicted``; ``p`` (A, O) the
        observation probabilities; ``post`` (O, total) the posteriors on those supports.
    """
    n_actions, n_obs = indptr.shape[0], Z.shape[2]
    bound = 0
    for a in range(n_actions):
        for i in range(len(support)):
            bound += indptr[a, support[i] + 1] - indptr[a, support[i]]
    states = np.empty(bound, dtype=np.int64)
    predicted = np.empty(bound)
    offsets = np.zeros(n_actions + 1, dtype=np.int64)
    found = np.empty(bound, dtype=np.int64)
    position = 0
    for a in range(n_actions):
        count = 0
        for i in range(len(support)):
            s, w = support[i], probs[i]
            for e in range(indptr[a, s], indptr[a, s + 1]):
                c = indices[e]
                if not touched[c]:
                    touched[c] = True
                    found[count] = c
                    count += 1
                accumulator[c] += w * data[e]
        ordered = np.sort(found[:count])
        for j in range(count):
            c = ordered[j]
            states[position + j] = c
            predicted[position + j] = accumulator[c]
            accumulator[c] = 0.0
            touched[c] = False
        position += count
        offsets[a + 1] = position
    states, predicted = states[:position], predicted[:position]
    p = np.zeros((n_actions, n_obs))
    post = np.zeros((n_obs, position))
    for a in range(n_actions):
        for j in range(offsets[a], offsets[a + 1]):
            for o in range(n_obs):
                v = predicted[j] * Z[a, states[j], o]
                post[o, j] = v
                p[a, o] += v
        for o in range(n_obs):
            if p[a, o] > 0.0:
                for j in range(offsets[a], offsets[a + 1]):
                    post[o, j] /= p[a, o]
    return offsets, states, predicted, p, post


@numba.njit(cache=True)
def _column_products(by_column, first, flushed, columns, rows, out):  # pragma: no cover
    """out[:, :flushed - first] += rows (R, m) @ by_column[first:flushed, columns].T, for
    the column-major (capacity, S) copy."""
    n = flushed - first
    for j in range(len(columns)):
        c = columns[j]
        for r in range(rows.shape[0]):
            w = rows[r, j]
            if w != 0.0:
                if first == 0:  # the search's case; kept apart so that it vectorises
                    for k in range(n):
                        out[r, k] += w * by_column[k, c]
                else:
                    for k in range(n):
                        out[r, k] += w * by_column[first + k, c]


@numba.njit(cache=True)
def alpha_products(store, first, columns, rows):  # pragma: no cover (compiled)
    """(R, count - first) = rows (R, m) @ alphas[first:count, columns].T, without gathering.

    ``store`` is :meth:`planning.pomdp.alpha_store.AlphaStore.view`: ``(by_column, flushed,
    by_row, count)``. Vectors below ``flushed`` are read from the column-major copy, where
    each state's values are contiguous (the loop over vectors vectorises); the few newer
    ones from the row-major one."""
    by_column, flushed, by_row, count = store
    n_rows = rows.shape[0]
    out = np.zeros((n_rows, count - first))
    if first < flushed:
        _column_products(by_column, first, flushed, columns, rows, out)
    for k in range(max(first, flushed), count):
        alpha = by_row[k]
        for r in range(n_rows):
            total = 0.0
            for j in range(len(columns)):
                total += rows[r, j] * alpha[columns[j]]
            out[r, k - first] = total
    return out


@numba.njit(cache=True)
def products_at_beliefs(store, first, offsets, states, probs):  # pragma: no cover
    """(B, count - first) values of the vectors ``first:`` at B beliefs stored flat: belief
    i is ``states[offsets[i]:offsets[i + 1]]`` with ``probs`` there."""
    n_beliefs = len(offsets) - 1
    out = np.empty((n_beliefs, store[3] - first))
    for i in range(n_beliefs):
        lo, hi = offsets[i], offsets[i + 1]
        out[i] = alpha_products(store, first, states[lo:hi], probs[lo:hi].reshape(1, hi - lo))[0]
    return out


@numba.njit(cache=True, parallel=True)
def best_backup(store, offsets, states, predicted, p, post, rewards,
                gamma):  # pragma: no cover (compiled)
    """The point-based backup's choice, on the output of :func:`expand`: for every action
    a, its value ``R(b, a) + g sum_o max_alpha sum_s' p(o, s' | b, a) alpha(s')`` and the
    best alpha per observation; an impossible observation takes the best alpha at the
    prediction. The actions are shared among numba's threads.

    Returns:
        (best value, best action (the first of equal values), (O,) alpha index per
        observation).
    """
    n_actions, n_obs = len(offsets) - 1, p.shape[1]
    totals = np.empty(n_actions)
    choices = np.empty((n_actions, n_obs), dtype=np.int64)
    for a in numba.prange(n_actions):
        lo, hi = offsets[a], offsets[a + 1]
        rows = np.empty((n_obs, hi - lo))
        for o in range(n_obs):
            for j in range(lo, hi):
                rows[o, j - lo] = post[o, j] * p[a, o]
        values = alpha_products(store, 0, states[lo:hi], rows)
        total = rewards[a]
        fallback, possible = -1, 0
        for o in range(n_obs):
            if p[a, o] > 0.0:
                choices[a, o] = np.argmax(values[o])
                total += gamma * values[o, choices[a, o]]
                possible += 1
                fallback = choices[a, o]
        if possible != 1:  # with one possible observation its posterior is the prediction
            fallback = -1
        for o in range(n_obs):
            if p[a, o] <= 0.0:
                if fallback < 0:  # only now is the prediction's own product needed
                    at_prediction = alpha_products(store, 0, states[lo:hi],
                                                   predicted[lo:hi].reshape(1, hi - lo))
                    fallback = np.argmax(at_prediction[0])
                choices[a, o] = fallback
        totals[a] = total
    best = np.argmax(totals)
    return totals[best], best, choices[best].copy()


@numba.njit(cache=True)
def new_alpha(by_row, row, choice, action, indptr, indices, data, Z, R,
              gamma):  # pragma: no cover (compiled)
    """Write into ``by_row[row]`` the backed-up alpha-vector (S,) of ``action`` with the
    vector ``choice[o]`` (rows of the row-major ``by_row``) after each observation:
    ``R[:, a] + g T[a] (sum_o Z[a, :, o] * alpha_choice[o])``."""
    n_states, n_obs = R.shape[0], Z.shape[2]
    g = np.zeros(n_states)
    for o in range(n_obs):
        chosen = by_row[choice[o]]
        for c in range(n_states):
            g[c] += Z[action, c, o] * chosen[c]
    out = by_row[row]
    for s in range(n_states):
        total = 0.0
        for e in range(indptr[action, s], indptr[action, s + 1]):
            total += data[e] * g[indices[e]]
        out[s] = R[s, action] + gamma * total


@numba.njit(cache=True)
def chain_point(head, next_point, excess, key, new):  # pragma: no cover (compiled)
    """Insert point ``new`` into the chain of state ``key`` (``head[key]``, then
    ``next_point``), which is kept in increasing order of ``excess``."""
    previous, i = -1, head[key]
    while i >= 0 and excess[i] < excess[new]:
        previous, i = i, next_point[i]
    next_point[new] = i
    if previous < 0:
        head[key] = new
    else:
        next_point[previous] = new


@numba.njit(cache=True)
def _sawtooth(head, next_point, starts, largest, excess, states, probs, support,
              scratch):  # pragma: no cover (compiled)
    """``min(0, min_i excess_i min_j b(states_ij) / probs_ij)`` for the belief scattered
    into ``scratch`` on the sorted ``support``, over the points whose smallest state is in
    the support (the chain ``head[s]``, ``next_point``) and whose largest is not beyond it;
    a ratio stops at its first zero."""
    end = support[-1]
    best = 0.0
    for j in range(len(support)):
        i = head[support[j]]
        while i >= 0:
            # the ratio is at most 1 (both beliefs sum to 1), so a point whose excess is
            # not below the best correction so far cannot lower it, nor can the rest of
            # its chain (ordered by excess, most negative first)
            if excess[i] >= best:
                break
            if largest[i] <= end:
                ratio = np.inf
                limit = best / excess[i]  # at or below it, this point cannot lower best
                for e in range(starts[i], starts[i + 1]):
                    r = scratch[states[e]] / probs[e]
                    if r < ratio:
                        ratio = r
                        if ratio <= limit:
                            break
                if ratio * excess[i] < best:
                    best = ratio * excess[i]
            i = next_point[i]
    return best


@numba.njit(cache=True)
def sawtooth_corrections(head, next_point, starts, largest, excess, states, probs, support,
                         beliefs, scratch):  # pragma: no cover (compiled)
    """(K,) sawtooth corrections (:func:`_sawtooth`) of (K, m) beliefs on the sorted
    ``support``. ``scratch`` is an all-zero (S,) buffer, zero again on return."""
    out = np.zeros(beliefs.shape[0])
    for k in range(beliefs.shape[0]):
        for j in range(len(support)):
            scratch[support[j]] = beliefs[k, j]
        out[k] = _sawtooth(head, next_point, starts, largest, excess, states, probs, support,
                           scratch)
        for j in range(len(support)):
            scratch[support[j]] = 0.0
    return out


@numba.njit(cache=True, parallel=True)
def child_uppers(offsets, kid_states, post, p, actions, corner, head, next_point, starts,
                 largest, excess, states, probs, scratch):  # pragma: no cover (compiled)
    """(A, O) the upper bound (corner values plus sawtooth correction) of every possible
    child of :func:`expand`'s output, for the listed ``actions``; 0 elsewhere. The actions
    are shared among numba's threads; ``scratch`` (A, S) is all zero, a row per action,
    and zero again on return."""
    out = np.zeros(p.shape)
    for i in numba.prange(len(actions)):
        a = actions[i]
        lo, hi = offsets[a], offsets[a + 1]
        if hi == lo:
            continue
        support = kid_states[lo:hi]
        dense = scratch[a]
        for o in range(p.shape[1]):
            if p[a, o] <= 0.0:
                continue
            value = 0.0
            for j in range(hi - lo):
                value += post[o, lo + j] * corner[support[j]]
                dense[support[j]] = post[o, lo + j]
            out[a, o] = value + _sawtooth(head, next_point, starts, largest, excess, states,
                                          probs, support, dense)
            for j in range(hi - lo):
                dense[support[j]] = 0.0
    return out


@numba.njit(cache=True)
def compact_columns(by_column_T, keep):  # pragma: no cover (compiled)
    """Move the kept vectors to the front of the column-major copy, in place:
    ``by_column_T`` (S, capacity) is its transposed (C-ordered) view and ``keep`` the sorted
    indices to keep; each state's row is compacted where it lies in memory."""
    for s in range(by_column_T.shape[0]):
        row = by_column_T[s]
        for j in range(len(keep)):
            row[j] = row[keep[j]]


@numba.njit(cache=True)
def compact_rows(by_row, keep):  # pragma: no cover (compiled)
    """Move the kept vectors (rows; ``keep`` sorted) to the front, in place."""
    for j in range(len(keep)):
        if keep[j] != j:
            by_row[j, :] = by_row[keep[j], :]
