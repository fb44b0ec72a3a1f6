"""The field's standard POMDP benchmarks, built in, for validating the solvers.

- :func:`tiger` (Kaelbling, Littman, Cassandra 1998): listen accuracy 0.85; listen -1,
  open the tiger's door -100, the other +10; opening resets the problem.
- :func:`tag` (Pineau, Gordon, Thrun 2003): 29 cells (a 10 x 2 corridor with a 3 x 3 room
  above columns 5-7), 870 states (robot cell x opponent cell or "tagged"), actions N, S,
  E, W, tag; the robot's cell is observed, and whether the opponent shares it. Moves cost
  1, a failed tag 10, a tag earns +10 and ends the episode. The opponent moves away from
  the robot: probability 0.4 split over the north/south moves that do not approach the
  robot (by map coordinates), 0.4 likewise east/west, the rest stays; a move into a wall
  leaves it in place (the original paper's rule).
- :func:`rock_sample` (Smith and Simmons 2004), (7, 8) in the standard layout: the robot
  starts at (0, 3); moving east off the map ends the episode with +10; sampling a good
  rock earns +10 (the rock turns bad), a bad rock or an empty cell -10; ``check_i``
  reports rock i's quality correctly with probability (1 + 2^(-d / 20)) / 2 at distance
  d. Discount 0.95 throughout.
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.sparse as sp

from planning.pomdp.tabular import TabularPOMDP

DISCOUNT = 0.95


def tiger(listen_accuracy: float = 0.85) -> TabularPOMDP:
    """The Tiger problem."""
    states = ("tiger-left", "tiger-right")
    actions = ("listen", "open-left", "open-right")
    observations = ("hear-left", "hear-right")
    stay = sp.identity(2, format="csr")
    reset = sp.csr_matrix(np.full((2, 2), 0.5))
    Z = np.empty((3, 2, 2))
    Z[0] = [[listen_accuracy, 1 - listen_accuracy], [1 - listen_accuracy, listen_accuracy]]
    Z[1:] = 0.5
    R = np.array([[-1.0, -100.0, 10.0], [-1.0, 10.0, -100.0]])
    return TabularPOMDP(states, actions, observations, (stay, reset, reset), Z, R, DISCOUNT,
                        np.array([0.5, 0.5]))


def _tag_cells() -> list[tuple[int, int]]:
    """(row, col) of Tag's 29 cells; row 0 is the bottom of the corridor."""
    return [(r, c) for r in range(2) for c in range(10)] + [
        (r, c) for r in range(2, 5) for c in range(5, 8)]


def tag() -> TabularPOMDP:
    """The Tag problem (870 states, 5 actions, 30 observations)."""
    cells = _tag_cells()
    index = {cell: i for i, cell in enumerate(cells)}
    n = len(cells)
    moves = {"north": (1, 0), "south": (-1, 0), "east": (0, 1), "west": (0, -1)}

    def step(cell, direction):
        dr, dc = moves[direction]
        target = (cell[0] + dr, cell[1] + dc)
        return index.get(target, index[cell])

    tagged = n  # opponent index meaning "tagged"
    S = n * (n + 1)

    def sid(robot, opponent):
        return robot * (n + 1) + opponent

    states = tuple(f"r{r}_o{o if o < n else 'tagged'}" for r in range(n) for o in range(n + 1))
    actions = ("north", "south", "east", "west", "tag")
    observations = tuple(f"robot{c}" for c in range(n)) + ("same",)
    rows, cols, vals = [[] for _ in actions], [[] for _ in actions], [[] for _ in actions]
    R = np.zeros((S, len(actions)))
    for r, o in itertools.product(range(n), range(n + 1)):
        s = sid(r, o)
        for a, name in enumerate(actions):
            if o == tagged:  # absorbing, no reward
                rows[a].append(s), cols[a].append(s), vals[a].append(1.0)
                continue
            if name == "tag":
                R[s, a] = 10.0 if r == o else -10.0
                if r == o:
                    rows[a].append(s), cols[a].append(sid(r, tagged)), vals[a].append(1.0)
                    continue
                new_r = r
            else:
                R[s, a] = -1.0
                new_r = step(cells[r], name)
            for new_o, p in _opponent_moves(cells, index, cells[r], cells[o], step).items():
                rows[a].append(s), cols[a].append(sid(new_r, new_o)), vals[a].append(p)
    T = tuple(sp.csr_matrix((vals[a], (rows[a], cols[a])), shape=(S, S))
              for a in range(len(actions)))
    Z = np.zeros((len(actions), S, n + 1))
    for r, o in itertools.product(range(n), range(n + 1)):
        Z[:, sid(r, o), n if o == r else r] = 1.0
    initial = np.zeros(S)
    for r, o in itertools.product(range(n), range(n)):
        initial[sid(r, o)] = 1.0 / (n * n)
    return TabularPOMDP(states, actions, observations, T, Z, R, DISCOUNT, initial)


def _opponent_moves(cells, index, robot, opponent, step) -> dict[int, float]:
    """Opponent's next cell distribution (see the module docstring)."""
    out: dict[int, float] = {}
    here = index[opponent]
    for axis, (toward_plus, toward_minus) in ((0, ("north", "south")), (1, ("east", "west"))):
        away = [d for d, ok in ((toward_plus, robot[axis] <= opponent[axis]),
                                (toward_minus, robot[axis] >= opponent[axis])) if ok]
        for direction in away:
            target = step(opponent, direction)
            out[target] = out.get(target, 0.0) + 0.4 / len(away)
    out[here] = out.get(here, 0.0) + 1.0 - sum(out.values())
    return out


ROCKS_7_8 = ((2, 0), (0, 1), (3, 1), (6, 3), (2, 4), (3, 4), (5, 5), (1, 6))
"""Rock (x, y) cells of the standard RockSample(7, 8) (x east, y north)."""


def rock_sample(size: int = 7, rocks: tuple[tuple[int, int], ...] = ROCKS_7_8,
                half_efficiency_distance: float = 20.0, *, wall_reward: float = 0.0,
                empty_sample_reward: float = -10.0) -> TabularPOMDP:
    """RockSample(size, len(rocks)); states are (x, y, rock qualities) plus "exit".

    ``wall_reward``: of a move into a wall other than the exit (the robot stays);
    ``empty_sample_reward``: of sampling a cell without a rock. The defaults are Smith and
    Simmons'; the reference DESPOT's RockSample charges -100 for both
    (:class:`planning.pomdp.rocksample.RockSample`)."""
    k = len(rocks)
    start = (0, size // 2)
    rock_at = {cell: i for i, cell in enumerate(rocks)}
    n_pos = size * size
    S = n_pos * 2**k + 1
    exit_state = S - 1
    actions = ("north", "south", "east", "west", "sample") + tuple(f"check{i}"
                                                                  for i in range(k))
    observations = ("none", "good", "bad")

    def sid(x, y, bits):
        return (y * size + x) * 2**k + bits

    states = tuple(f"x{x}_y{y}_r{bits:0{k}b}" for y in range(size) for x in range(size)
                   for bits in range(2**k)) + ("exit",)
    A = len(actions)
    rows, cols = [[] for _ in range(A)], [[] for _ in range(A)]
    R = np.zeros((S, A))
    Z = np.zeros((A, S, 3))
    Z[:, :, 0] = 1.0
    for y, x, bits in itertools.product(range(size), range(size), range(2**k)):
        s = sid(x, y, bits)
        for a, name in enumerate(actions):
            target = s
            if name in ("north", "south", "west"):
                dx, dy = {"north": (0, 1), "south": (0, -1), "west": (-1, 0)}[name]
                nx, ny = x + dx, y + dy
                if 0 <= nx < size and 0 <= ny < size:
                    target = sid(nx, ny, bits)
                else:
                    R[s, a] = wall_reward
            elif name == "east":
                if x + 1 < size:
                    target = sid(x + 1, y, bits)
                else:
                    target, R[s, a] = exit_state, 10.0
            elif name == "sample":
                rock = rock_at.get((x, y))
                if rock is None:
                    R[s, a] = empty_sample_reward
                elif bits >> rock & 1:
                    R[s, a] = 10.0
                    target = sid(x, y, bits & ~(1 << rock))
                else:
                    R[s, a] = -10.0
            rows[a].append(s)
            cols[a].append(target)
        for i, (rx, ry) in enumerate(rocks):
            eta = (1.0 + 2.0 ** (-np.hypot(rx - x, ry - y) / half_efficiency_distance)) / 2
            good = bool(bits >> i & 1)
            Z[5 + i, s] = [0.0, eta if good else 1 - eta, 1 - eta if good else eta]
    for a in range(A):
        rows[a].append(exit_state)
        cols[a].append(exit_state)
    T = tuple(sp.csr_matrix((np.ones(len(rows[a])), (rows[a], cols[a])), shape=(S, S))
              for a in range(A))
    initial = np.zeros(S)
    for bits in range(2**k):
        initial[sid(start[0], start[1], bits)] = 1.0 / 2**k
    return TabularPOMDP(states, actions, observations, T, Z, R, DISCOUNT, initial)
