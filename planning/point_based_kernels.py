"""Compiled inner loops of the point-based solver (:mod:`planning.point_based`).

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
def alpha_products(buffer, count, columns, rows):  # pragma: no cover (compiled)
    """(R, count) = rows (R, m) @ buffer[:count, columns].T without gathering the columns:
    the buffer is column-major, so each column's alphas are contiguous."""
    out = np.zeros((rows.shape[0], count))
    for j in range(len(columns)):
        c = columns[j]
        for r in range(rows.shape[0]):
            w = rows[r, j]
            if w != 0.0:
                for k in range(count):
                    out[r, k] += w * buffer[k, c]
    return out


@numba.njit(cache=True)
def best_backup(buffer, count, offsets, states, predicted, p, post, rewards,
                gamma):  # pragma: no cover (compiled)
    """The point-based backup's choice, on the output of :func:`expand`: for every action
    a, its value ``R(b, a) + g sum_o max_alpha sum_s' p(o, s' | b, a) alpha(s')`` and the
    best alpha per observation; an impossible observation takes the best alpha at the
    prediction.

    Returns:
        (best value, best action, (O,) alpha index per observation).
    """
    n_actions, n_obs = len(offsets) - 1, p.shape[1]
    best_value, best_action = -np.inf, -1
    best_choice = np.zeros(n_obs, dtype=np.int64)
    for a in range(n_actions):
        lo, hi = offsets[a], offsets[a + 1]
        rows = np.empty((n_obs, hi - lo))
        for o in range(n_obs):
            for j in range(lo, hi):
                rows[o, j - lo] = post[o, j] * p[a, o]
        values = alpha_products(buffer, count, states[lo:hi], rows)
        choice = np.empty(n_obs, dtype=np.int64)
        total = rewards[a]
        fallback = -1
        for o in range(n_obs):
            if p[a, o] > 0.0:
                choice[o] = np.argmax(values[o])
                total += gamma * values[o, choice[o]]
            else:
                if fallback < 0:  # only now is the prediction's own product needed
                    at_prediction = alpha_products(buffer, count, states[lo:hi],
                                                   predicted[lo:hi].reshape(1, hi - lo))
                    fallback = np.argmax(at_prediction[0])
                choice[o] = fallback
        if total > best_value:
            best_value, best_action, best_choice = total, a, choice
    return best_value, best_action, best_choice


@numba.njit(cache=True)
def new_alpha(buffer, choice, action, indptr, indices, data, Z, R,
              gamma):  # pragma: no cover (compiled)
    """The backed-up alpha-vector (S,) of ``action`` with alpha index ``choice[o]`` after
    each observation: ``R[:, a] + g T[a] (sum_o Z[a, :, o] * alpha_choice[o])``."""
    n_states, n_obs = R.shape[0], Z.shape[2]
    g = np.zeros(n_states)
    for c in range(n_states):
        for o in range(n_obs):
            g[c] += Z[action, c, o] * buffer[choice[o], c]
    alpha = np.empty(n_states)
    for s in range(n_states):
        total = 0.0
        for e in range(indptr[action, s], indptr[action, s + 1]):
            total += data[e] * g[indices[e]]
        alpha[s] = R[s, action] + gamma * total
    return alpha


@numba.njit(cache=True)
def sawtooth(points, probs, starts, hi, excess, end, belief):  # pragma: no cover (compiled)
    """min(0, min_i excess_i min_j belief[points_ij] / probs_ij) over the points of one
    group whose largest state is at most ``end``; a ratio stops at its first zero."""
    best = 0.0
    for i in range(len(excess)):
        if hi[i] > end:
            continue
        ratio = np.inf
        for j in range(starts[i], starts[i + 1]):
            r = belief[points[j]] / probs[j]
            if r < ratio:
                ratio = r
                if ratio == 0.0:
                    break
        if ratio * excess[i] < best:
            best = ratio * excess[i]
    return best


@numba.njit(cache=True)
def compact_alphas(buffer_T, keep):  # pragma: no cover (compiled)
    """Move the kept alpha-vectors to the front, in place: ``buffer_T`` (S, capacity) is the
    transposed (C-ordered) view of the column-major alpha buffer and ``keep`` the sorted
    indices to keep; each state's row is compacted where it lies in memory."""
    for s in range(buffer_T.shape[0]):
        row = buffer_T[s]
        for j in range(len(keep)):
            row[j] = row[keep[j]]
