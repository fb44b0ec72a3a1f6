"""RockSample(n, k) (Smith and Simmons 2004) as a native batched generative POMDP.

The rules and layouts of the reference DESPOT (AdaCompNUS/despot,
``examples/cpp_models/rock_sample``): an n x n grid, the robot starting at (0, n // 2);
moving east off the map ends the episode with +10; a move into another wall, or sampling
a cell without a rock, costs -100 (and leaves the robot where it is); sampling a good rock
earns +10 and makes it bad, a bad one -10; ``check_i`` reports rock i's quality correctly
with probability (1 + 2^(-d / 20)) / 2 at Euclidean distance d. Each rock is good with
probability 1/2. Discount 0.95. Layouts: the reference's fixed ones for (7, 8) and
(11, 11) (:data:`LAYOUTS`; (7, 8) is also the tabular builder's), any other (n, k) drawn
from a seeded generator, as the reference does for (15, 15) (with its own generator, so
the rocks lie elsewhere than in its runs).

A state is (x, y, rock bits) as int64, x = n meaning "exited" (terminal). Actions: north,
south, east, west, sample, check_0 .. check_{k-1} (the tabular builder's order).
Observations: 0 none, 1 good, 2 bad.

Bounds for DESPOT, the reference's defaults: the upper bound is the value with every
rock's quality known (a dynamic programme over rock subsets: from a rock, go to the
next good rock or exit, :func:`full_information_values`); the default policy moves east
to the exit, whose return is 10 gamma^(n - 1 - x) in closed form.
"""

from __future__ import annotations

import numba
import numpy as np

from planning.pomdp.benchmarks import ROCKS_7_8
from planning.pomdp.generative import GenerativeStep, action_array

ROCKS_11_11 = ((0, 3), (0, 7), (1, 8), (2, 4), (3, 3), (3, 8), (4, 3), (5, 8), (6, 1),
               (9, 3), (9, 9))
"""The reference's RockSample(11, 11) rocks (``Init_11_11``; x east, y north)."""

LAYOUTS = {(7, 8): ROCKS_7_8, (11, 11): ROCKS_11_11}
"""Fixed layouts (rock cells) by (n, k); the robot starts at (0, n // 2) in all."""

NORTH, SOUTH, EAST, WEST, SAMPLE = range(5)
NONE, GOOD, BAD = 0, 1, 2


def layout(size: int, rocks: int, *, seed: int = 0) -> tuple[tuple[int, int], ...]:
    """The rock cells of RockSample(size, rocks): the fixed layout where there is one,
    else ``rocks`` distinct cells drawn with ``seed``."""
    if size < 2 or not 1 <= rocks <= min(size * size - 1, 30):
        raise ValueError(f"RockSample({size}, {rocks}): need size >= 2 and 1 <= rocks <= "
                         f"min(size^2 - 1, 30)")
    if (size, rocks) in LAYOUTS:
        return LAYOUTS[(size, rocks)]
    cells = np.random.default_rng(seed).choice(size * size, size=rocks, replace=False)
    return tuple((int(c % size), int(c // size)) for c in cells)


class RockSample:
    """The native RockSample model (see the module docstring); states (K, 3) int64.

    Args:
        size, rocks: n and k.
        seed: draws the layout when (n, k) has no fixed one.
        half_efficiency_distance: d0 of the sensor (reference: 20).
        illegal_reward: reward of a move into a wall other than the exit, and of sampling
            an empty cell (reference: -100).
    """

    uniforms_per_step = 1

    def __init__(self, size: int = 7, rocks: int = 8, *, seed: int = 0,
                 half_efficiency_distance: float = 20.0, illegal_reward: float = -100.0):
        self.size, self.rock_count = size, rocks
        self.rocks = np.array(layout(size, rocks, seed=seed), dtype=np.int64)
        self.start = (0, size // 2)
        self.discount = 0.95
        self.half_efficiency_distance = half_efficiency_distance
        self.illegal_reward = illegal_reward
        self.actions = ("north", "south", "east", "west", "sample") + tuple(
            f"check{i}" for i in range(rocks))
        self._rock_at = np.full((size, size), -1, dtype=np.int64)
        self._rock_at[self.rocks[:, 0], self.rocks[:, 1]] = np.arange(rocks)
        self._from_rock = full_information_values(self.rocks, size, self.discount)
        self._table = None
        if size * size * 2 ** rocks <= 2 ** 23:
            x, y, bits = np.meshgrid(np.arange(size), np.arange(size), np.arange(2 ** rocks),
                                     indexing="ij")
            self._table = self._full_information(x.ravel(), y.ravel(), bits.ravel()).reshape(
                x.shape)

    # -- the model
    def step(self, states: np.ndarray, actions, u: np.ndarray) -> GenerativeStep:
        x, y, bits = states[:, 0].copy(), states[:, 1].copy(), states[:, 2].copy()
        a = action_array(actions, len(states))
        n = self.size
        done = x >= n
        rewards = np.zeros(len(states))
        observations = np.full(len(states), NONE, dtype=np.int64)
        live = ~done
        move_north = live & (a == NORTH)
        move_south = live & (a == SOUTH)
        move_west = live & (a == WEST)
        move_east = live & (a == EAST)
        rewards[move_north & (y + 1 >= n)] = self.illegal_reward
        rewards[move_south & (y - 1 < 0)] = self.illegal_reward
        rewards[move_west & (x - 1 < 0)] = self.illegal_reward
        y = np.where(move_north & (y + 1 < n), y + 1, y)
        y = np.where(move_south & (y - 1 >= 0), y - 1, y)
        exits = move_east & (x + 1 >= n)
        rewards[exits] = 10.0
        x = np.where(move_west & (x - 1 >= 0), x - 1, x)
        x = np.where(move_east, x + 1, x)  # x = n: exited
        sample = live & (a == SAMPLE)
        if sample.any():
            rows = np.flatnonzero(sample)
            rock = self._rock_at[x[rows], y[rows]]
            has = rock >= 0
            good = has & ((bits[rows] >> np.maximum(rock, 0)) & 1 == 1)
            rewards[rows] = np.where(has, np.where(good, 10.0, -10.0), self.illegal_reward)
            bits[rows[has]] &= ~(1 << rock[has])
        check = live & (a > SAMPLE)
        if check.any():
            rows = np.flatnonzero(check)
            rock = a[rows] - SAMPLE - 1
            good = (bits[rows] >> rock) & 1 == 1
            correct = u[rows, 0] < self._efficiency(x[rows], y[rows], rock)
            observations[rows] = np.where(good == correct, GOOD, BAD)
        return GenerativeStep(np.column_stack([x, y, bits]), rewards, observations, x >= n)

    def _efficiency(self, x, y, rock) -> np.ndarray:
        d = np.hypot(x - self.rocks[rock, 0], y - self.rocks[rock, 1])
        return (1.0 + 2.0 ** (-d / self.half_efficiency_distance)) / 2.0

    def log_likelihood(self, observation: int, states: np.ndarray, action: int) -> np.ndarray:
        if action <= SAMPLE:
            return np.where(observation == NONE, 0.0, -np.inf) * np.ones(len(states))
        if observation == NONE:
            return np.full(len(states), -np.inf)
        rock = action - SAMPLE - 1
        x = np.minimum(states[:, 0], self.size - 1)
        eta = self._efficiency(x, states[:, 1], rock)
        good = (states[:, 2] >> rock) & 1 == 1
        with np.errstate(divide="ignore"):  # a certain sensor: log 0 = -inf
            return np.log(np.where(good == (observation == GOOD), eta, 1.0 - eta))

    def sample_initial(self, n: int, *, rng: np.random.Generator) -> np.ndarray:
        bits = rng.integers(0, 2 ** self.rock_count, size=n)
        return np.column_stack([np.full(n, self.start[0]), np.full(n, self.start[1]), bits])

    def is_terminal(self, states: np.ndarray) -> np.ndarray:
        return states[:, 0] >= self.size

    def state_index(self, states: np.ndarray) -> np.ndarray:
        """(K,) the tabular builder's state index (exit last)."""
        k = self.rock_count
        exited = states[:, 0] >= self.size
        index = (states[:, 1] * self.size + states[:, 0]) * 2 ** k + states[:, 2]
        return np.where(exited, self.size * self.size * 2 ** k, index)

    # -- bounds
    def upper_bound(self, states: np.ndarray) -> np.ndarray:
        """The value with every rock's quality known (see :func:`full_information_values`);
        a table lookup when the table (n^2 2^k values) is at most 2^23 entries."""
        if self._table is not None:
            x = np.minimum(states[:, 0], self.size - 1)
            return np.where(states[:, 0] >= self.size, 0.0,
                            self._table[x, states[:, 1], states[:, 2]])
        return self._full_information(states[:, 0], states[:, 1], states[:, 2])

    def _full_information(self, x, y, bits) -> np.ndarray:
        gamma, n = self.discount, self.size
        best = 10.0 * gamma ** np.maximum(n - 1 - x, 0)
        for i, (rx, ry) in enumerate(self.rocks):
            good = (bits >> i) & 1 == 1
            d = np.abs(x - rx) + np.abs(y - ry)
            rest = self._from_rock[i, bits & ~(1 << i)]
            best = np.where(good, np.maximum(best, gamma ** d * (10.0 + gamma * rest)), best)
        return np.where(x >= n, 0.0, best)

    def kernels(self):
        """The compiled DESPOT's kernels and their parameters (only with the table of the
        upper bound: see :meth:`upper_bound`)."""
        if self._table is None:
            return None
        return (rocksample_step, rocksample_upper, rocksample_rollout), (
            self.size, self.rocks, self._rock_at, float(self.illegal_reward),
            float(self.half_efficiency_distance), self._table)

    def default_actions(self, states: np.ndarray) -> np.ndarray:
        """East, to the exit (the reference's default lower bound)."""
        return np.full(len(states), EAST, dtype=np.int64)

    def rollout(self, states, scenarios, depths, offsets, uniforms, max_depth) -> np.ndarray:
        """The east policy's return, 10 gamma^(n - 1 - x) when the exit is reached before
        the depth limit, else 0 (no uniforms needed: the policy is deterministic)."""
        steps = self.size - 1 - states[:, 0]
        reached = (states[:, 0] < self.size) & (depths + steps < max_depth)
        return np.where(reached, 10.0 * self.discount ** np.maximum(steps, 0), 0.0)


@numba.njit
def rocksample_step(params, state, action, u, out):  # pragma: no cover (compiled)
    """One scenario of :meth:`RockSample.step`."""
    size, rocks, rock_at, illegal, d0, table = params
    x, y, bits = int(state[0]), int(state[1]), int(state[2])
    out[0], out[1], out[2] = x, y, bits
    if x >= size:
        return 0.0, NONE, True
    if action == NORTH:
        if y + 1 < size:
            out[1] = y + 1
            return 0.0, NONE, False
        return illegal, NONE, False
    if action == SOUTH:
        if y - 1 >= 0:
            out[1] = y - 1
            return 0.0, NONE, False
        return illegal, NONE, False
    if action == WEST:
        if x - 1 >= 0:
            out[0] = x - 1
            return 0.0, NONE, False
        return illegal, NONE, False
    if action == EAST:
        out[0] = x + 1
        if x + 1 >= size:
            return 10.0, NONE, True
        return 0.0, NONE, False
    if action == SAMPLE:
        rock = rock_at[x, y]
        if rock < 0:
            return illegal, NONE, False
        good = (bits >> rock) & 1
        out[2] = bits & ~(1 << rock)
        return (10.0 if good else -10.0), NONE, False
    rock = action - SAMPLE - 1
    distance = np.hypot(x - rocks[rock, 0], y - rocks[rock, 1])
    efficiency = (1.0 + 2.0 ** (-distance / d0)) / 2.0
    good = (bits >> rock) & 1 == 1
    correct = u[0] < efficiency
    return 0.0, (GOOD if good == correct else BAD), False


@numba.njit
def rocksample_upper(params, state):  # pragma: no cover (compiled)
    table = params[5]
    return table[int(state[0]), int(state[1]), int(state[2])]


@numba.njit
def rocksample_rollout(params, states, scenarios, terminal_rows, depth, uniforms, max_depth,
                       discount):  # pragma: no cover (compiled)
    """The east policy's returns over one node's scenarios, summed (closed form)."""
    size = params[0]
    total = 0.0
    for i in range(len(states)):
        x = int(states[i, 0])
        if terminal_rows[i] or x >= size:
            continue
        steps = size - 1 - x
        if depth + steps < max_depth:
            total += 10.0 * discount ** steps
    return total


def full_information_values(rocks: np.ndarray, size: int, gamma: float) -> np.ndarray:
    """(k, 2^k) the optimal value of the robot standing on rock i (after sampling it),
    with the set ``bits`` of good rocks left, knowing every quality: exit east, or walk
    (Manhattan distance d) to a good rock j and sample it, 10 gamma^d plus gamma^(d + 1)
    times the value from there. Subsets in order of size, vectorised over them."""
    k = len(rocks)
    distance = np.abs(rocks[:, None, :] - rocks[None, :, :]).sum(axis=2)
    values = np.zeros((k, 2 ** k))
    exit_value = 10.0 * gamma ** (size - 1 - rocks[:, 0])
    subsets = np.arange(2 ** k)
    popcount = np.array([bin(b).count("1") for b in subsets])
    for count in range(k + 1):
        layer = subsets[popcount == count]
        best = np.repeat(exit_value[:, None], len(layer), axis=1)
        for j in range(k):
            has = (layer >> j) & 1 == 1
            if not has.any():
                continue
            rest = values[j, layer[has] & ~(1 << j)]
            gain = gamma ** distance[:, j, None] * (10.0 + gamma * rest[None, :])
            best[:, has] = np.maximum(best[:, has], gain)
        values[:, layer] = best
    return values
