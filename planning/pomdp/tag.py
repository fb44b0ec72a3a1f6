"""Tag (Pineau, Gordon and Thrun 2003) as a native batched generative POMDP.

The same problem as the tabular :func:`planning.pomdp.benchmarks.tag` (its docstring gives
the map, rewards and the opponent's motion; the tests check that the two agree), stepped
for K scenarios at once from tables: a state is (robot cell, opponent cell), the opponent
cell 29 meaning "tagged" (terminal); one uniform per step draws the opponent's move.
Observations: the robot's cell (0-28), or 29 when the opponent shares it.

Bounds for DESPOT: the upper bound is the MDP value of the state (value iteration on the
tabular model, 870 states); the default policy is the reference's kind of particle-set
policy, open-loop over a node's belief: tag when the robot sees the opponent in its cell,
else take the MDP action towards the node's most frequent opponent cell (all of a node's
scenarios share the robot's cell, which the robot observes). Both compiled into one
rollout kernel (:func:`tag_rollout`).
"""

from __future__ import annotations

import numba
import numpy as np

from planning.pomdp.benchmarks import _opponent_moves, _tag_cells, tag
from planning.pomdp.generative import GenerativeStep, action_array, inverse_cdf
from planning.pomdp.qmdp import solve_mdp

TAG_ACTION = 4
MOVES = {"north": (1, 0), "south": (-1, 0), "east": (0, 1), "west": (0, -1)}


class Tag:
    """The native Tag model (see the module docstring); states (K, 2) int64."""

    uniforms_per_step = 1

    def __init__(self):
        tabular = tag()
        self.discount = tabular.discount
        self.actions = tabular.actions
        cells = _tag_cells()
        index = {cell: i for i, cell in enumerate(cells)}
        n = self.cells = len(cells)
        self.tagged = n

        def step(cell, direction):
            dr, dc = MOVES[direction]
            return index.get((cell[0] + dr, cell[1] + dc), index[cell])

        self._move = np.array([[step(c, d) for d in MOVES] + [index[c]] for c in cells])
        width = 5
        self._opp_next = np.zeros((n, n, width), dtype=np.int64)
        self._opp_cum = np.ones((n, n, width))
        for r in range(n):
            for o in range(n):
                moves = _opponent_moves(cells, index, cells[r], cells[o], step)
                targets = sorted(moves)
                self._opp_next[r, o, :len(targets)] = targets
                self._opp_next[r, o, len(targets):] = targets[-1]
                self._opp_cum[r, o, :len(targets)] = np.cumsum([moves[t] for t in targets])
        q = solve_mdp(tabular).reshape(n, n + 1, len(self.actions))
        self._value = q.max(axis=2)
        self._mdp_action = q.argmax(axis=2)
        self.rollout(np.zeros((1, 2), dtype=np.int64), np.zeros(1, dtype=np.int64),
                     np.zeros(1, dtype=np.int64), np.array([0, 1]), np.zeros((1, 2, 1)), 1)
        # (compiles, or loads the cached kernel, now rather than in the first decision)

    def state_index(self, states: np.ndarray) -> np.ndarray:
        """(K,) the tabular model's state index of each state."""
        return states[:, 0] * (self.cells + 1) + states[:, 1]

    def step(self, states: np.ndarray, actions, u: np.ndarray) -> GenerativeStep:
        r, o = states[:, 0], states[:, 1]
        a = action_array(actions, len(states))
        done = o == self.tagged
        is_tag = a == TAG_ACTION
        caught = is_tag & (r == o) & ~done
        rewards = np.where(is_tag, np.where(r == o, 10.0, -10.0), -1.0)
        rewards[done] = 0.0
        new_r = np.where(done, r, self._move[r, np.minimum(a, TAG_ACTION)])
        o_live = np.minimum(o, self.cells - 1)
        pick = inverse_cdf(self._opp_cum[r, o_live], u[:, 0])
        new_o = self._opp_next[r, o_live, pick]
        new_o = np.where(done | caught, self.tagged, new_o)
        observations = np.where(new_o == new_r, self.cells, new_r)
        return GenerativeStep(np.column_stack([new_r, new_o]), rewards, observations,
                              new_o == self.tagged)

    def log_likelihood(self, observation: int, states: np.ndarray, action: int) -> np.ndarray:
        r, o = states[:, 0], states[:, 1]
        expected = np.where(o == r, self.cells, r)
        return np.where(expected == observation, 0.0, -np.inf)

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        """Robot and opponent uniform over the cells, independently."""
        return rng.integers(0, self.cells, size=(n, 2))

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        return states[:, 1] == self.tagged

    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        return self._value[states[:, 0], states[:, 1]]

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        """For one node's scenarios: tag if the robot sees the opponent (it shares the
        cell), else the MDP action towards the most frequent opponent cell."""
        r = states[:, 0]
        live = states[:, 1] != self.tagged
        counts = np.bincount(states[live, 1], minlength=self.cells + 1) if live.any() \
            else np.bincount(states[:, 1], minlength=self.cells + 1)
        mode = int(np.argmax(counts))
        return np.where(states[:, 1] == r, TAG_ACTION, self._mdp_action[r, mode])

    def rollout(self, states, scenarios, depths, offsets, uniforms, max_depth) -> np.ndarray:
        """The default policy's returns, compiled (:func:`tag_rollout`)."""
        return tag_rollout(np.ascontiguousarray(states), scenarios, depths, offsets, uniforms,
                           max_depth, self.discount, self._move, self._opp_next,
                           self._opp_cum, self._mdp_action, self.cells)


    def kernels(self):
        """The compiled DESPOT's kernels and their parameters
        (:func:`planning.pomdp.despot_kernels.make_core`)."""
        return (tag_step, tag_upper, tag_node_rollout), (
            self._move, self._opp_next, self._opp_cum, self._mdp_action, self._value,
            self.cells)


@numba.njit
def tag_step(params, state, action, u, out):  # pragma: no cover (compiled)
    """One scenario of :meth:`Tag.step`."""
    move, opp_next, opp_cum, mdp_action, value, cells = params
    r, o = int(state[0]), int(state[1])
    if o == cells:
        out[0], out[1] = r, o
        return 0.0, r, True
    if action == TAG_ACTION and r == o:
        out[0], out[1] = r, cells
        return 10.0, r, True
    reward = -10.0 if action == TAG_ACTION else -1.0
    new_r = move[r, min(action, TAG_ACTION)]
    k = 0
    while k < opp_cum.shape[2] - 1 and u[0] >= opp_cum[r, o, k]:
        k += 1
    new_o = opp_next[r, o, k]
    out[0], out[1] = new_r, new_o
    return reward, (cells if new_o == new_r else new_r), False


@numba.njit
def tag_upper(params, state):  # pragma: no cover (compiled)
    return params[4][int(state[0]), int(state[1])]


@numba.njit
def tag_node_rollout(params, states, scenarios, terminal_rows, depth, uniforms, max_depth,
                     discount):  # pragma: no cover (compiled)
    """:func:`tag_rollout` of one node, summed over its scenarios."""
    move, opp_next, opp_cum, mdp_action, value, cells = params
    n = len(states)
    as_int = np.empty((n, 2), dtype=np.int64)
    for i in range(n):
        as_int[i, 0], as_int[i, 1] = int(states[i, 0]), int(states[i, 1])
    offsets = np.array([0, n])
    depths = np.full(n, depth)
    returns = tag_rollout(as_int, scenarios, depths, offsets, uniforms, max_depth, discount,
                          move, opp_next, opp_cum, mdp_action, cells)
    total = 0.0
    for i in range(n):
        if not terminal_rows[i]:
            total += returns[i]
    return total


@numba.njit(cache=True)
def tag_rollout(states, scenarios, depths, offsets, uniforms, max_depth, discount, move,
                opp_next, opp_cum, mdp_action, cells):  # pragma: no cover (compiled)
    """Returns of :meth:`Tag.default_actions` for each node ``offsets[j]:offsets[j + 1]``,
    all of a node's scenarios stepped together (the mode is taken over the node's live
    scenarios at each depth)."""
    out = np.zeros(len(states))
    for j in range(len(offsets) - 1):
        lo, hi = offsets[j], offsets[j + 1]
        r = states[lo:hi, 0].copy()
        o = states[lo:hi, 1].copy()
        scale = 1.0
        depth = depths[lo]
        counts = np.zeros(cells + 1, dtype=np.int64)
        while depth < max_depth:
            counts[:] = 0
            alive = 0
            for i in range(hi - lo):
                if o[i] != cells:
                    counts[o[i]] += 1
                    alive += 1
            if alive == 0:
                break
            mode = np.argmax(counts)
            for i in range(hi - lo):
                if o[i] == cells:
                    continue
                if o[i] == r[i]:
                    out[lo + i] += scale * 10.0
                    o[i] = cells
                    continue
                a = mdp_action[r[i], mode]
                old_r = r[i]
                if a == 4:
                    out[lo + i] -= scale * 10.0
                else:
                    out[lo + i] -= scale
                    r[i] = move[old_r, a]
                u = uniforms[scenarios[lo + i], depth, 0]
                k = 0
                while k < opp_cum.shape[2] - 1 and u >= opp_cum[old_r, o[i], k]:
                    k += 1
                o[i] = opp_next[old_r, o[i], k]
            scale *= discount
            depth += 1
    return out
