"""The hand-relative planning POMDP, built by Monte Carlo from the continuous planar model
(thesis sec. 6.2.2 and 6.4.1).

"We compute the transition, observation, and reward functions for the discrete state space
by taking an expectation over the corresponding continuous models [...] with Monte Carlo
sampling by assuming a uniform distribution over the aggregation of continuous states that
map to each discrete state." For every discrete state we draw ``samples_per_state`` poses
uniformly from its aggregation (:class:`~planning.hand.discretization.HandDiscretization`)
and, for each action, push them with the planar pushing model and count where they land:

- ``T[a][s, s']``: fraction of the samples of ``s`` that land in ``s'``;
- ``Z[a, s', o]``: the mean of ``p(o | x)`` over the samples ``x`` of ``s'`` (the sensors
  read the state after the action, so Z is the same for every action);
- ``R[s, a]``: ``-(1 - fraction of samples of s inside the goal region)``, the thesis'
  reward (0 in the goal, -1 elsewhere; sec. 3.4) in expectation over the cell.

The sentinel state (outside the trust region) is absorbing, earns -1 and reads no contact,
as the lattice's ``s_bad`` of sec. 7.1. Cells that no sample can occupy (inside the hand,
contour pieces outside the trust region) are dropped from the model.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from tqdm import tqdm

from models.planar.observation import observation_keys
from models.planar.world import PlanarWorld
from planning.hand.discretization import HandDiscretization, HandProblemSpec
from planning.pomdp.tabular import TabularPOMDP


@dataclass
class HandPOMDP:
    """The discrete model with the maps between it and the continuous world.

    Attributes:
        pomdp: the tabular model (its ``initial`` is uniform over the free states; planners
            pass their own beliefs).
        discretization: the raw cell map.
        kept: (S_raw,) new index of each raw cell, or -1 where the cell was dropped.
        spec: the problem parameters.
        world: the continuous planar world the tables were sampled from.
        build_seconds: wall time spent building the tables (s).
    """

    pomdp: TabularPOMDP
    discretization: HandDiscretization
    kept: np.ndarray
    spec: HandProblemSpec
    world: PlanarWorld
    build_seconds: float = 0.0

    @property
    def sentinel(self) -> int:
        return len(self.pomdp.states) - 1

    @property
    def free_count(self) -> int:
        """Number of free-space states (they come first)."""
        return int(np.count_nonzero(self.kept[:self.discretization.free_count] >= 0))

    @property
    def contact_count(self) -> int:
        return len(self.pomdp.states) - 1 - self.free_count

    def index(self, poses: np.ndarray) -> np.ndarray:
        """(K,) model state of each (K, 3) pose; dropped cells count as outside."""
        raw = self.discretization.index(poses)
        out = self.kept[raw]
        return np.where(out >= 0, out, self.sentinel)

    def belief(self, poses: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        """(S,) discrete belief of weighted poses (a particle set): the histogram of their
        states."""
        w = np.full(len(poses), 1.0 / len(poses)) if weights is None else weights / weights.sum()
        return np.bincount(self.index(poses), weights=w, minlength=len(self.pomdp.states))

    def in_goal(self, poses: np.ndarray) -> np.ndarray:
        """(K,) whether each object centre lies in the goal region (hand frame)."""
        return in_goal(self.world, self.spec, poses)

    def observation_index(self, observation: np.ndarray) -> int:
        """Model observation of a (S,) boolean sensor reading."""
        return int(observation_keys(np.atleast_2d(observation))[0])


def goal_region(world: PlanarWorld, spec: HandProblemSpec) -> np.ndarray:
    """(2, 2) [[x_lo, y_lo], [x_hi, y_hi]] of the goal region (m, hand frame): ``goal_depth_m``
    deep from the hand's front (its largest x), ``goal_width_m`` wide about its axis."""
    front = float(world.hand.parts.vertices[..., 0][world.hand.parts.valid].max())
    half = spec.goal_width_m / 2
    return np.array([[front, -half], [front + spec.goal_depth_m, half]])


def in_goal(world: PlanarWorld, spec: HandProblemSpec, poses: np.ndarray) -> np.ndarray:
    (x0, y0), (x1, y1) = goal_region(world, spec)
    x, y = poses[:, 0], poses[:, 1]
    return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def build_hand_pomdp(world: PlanarWorld, spec: HandProblemSpec = HandProblemSpec(), *,
                     rng: np.random.Generator, progress: bool = True) -> HandPOMDP:
    """Sample T, Z and R of the hand-relative problem (see the module docstring).

    Cost: ``samples_per_state`` x (states) pushes of one action each, per action; with the
    defaults about 300k pushes of 2-3 cm per action.
    """
    start = time.perf_counter()
    disc = HandDiscretization(world, spec)
    n = spec.samples_per_state
    free_poses, free_state = disc.sample_free(n, rng=rng)
    contact_poses, contact_state = disc.sample_contact(n, rng=rng)
    poses = np.vstack([free_poses, contact_poses])
    raw_state = np.concatenate([free_state, contact_state])

    # compact: keep the cells that have samples, plus the sentinel
    occupied = np.zeros(disc.state_count, dtype=bool)
    occupied[raw_state] = True
    occupied[disc.sentinel] = True
    kept = np.where(occupied, np.cumsum(occupied) - 1, -1)
    S = int(occupied.sum())
    sentinel = S - 1
    state = kept[raw_state]
    count = np.bincount(state, minlength=S).astype(float)
    weight = 1.0 / count[state]

    def to_model(raw):
        out = kept[raw]
        return np.where(out >= 0, out, sentinel)

    actions = spec.action_vectors()
    n_obs = 2 ** world.sensor_count
    T, Z = [], []
    steps = tqdm(actions, desc="hand POMDP transitions", unit="action", disable=not progress)
    for action in steps:
        moved = world.sample_step(poses, action, rng=rng)
        landed = to_model(disc.index(moved))
        rows = np.concatenate([state, [sentinel]])
        cols = np.concatenate([landed, [sentinel]])
        vals = np.concatenate([weight, [1.0]])
        T.append(sp.csr_matrix((vals, (rows, cols)), shape=(S, S)))
        if not spec.contact_states:  # a cell's readings: where the action's pushes land
            Z.append(_observations(world, moved, landed, weight, S, n_obs,
                                   fallback=(poses, state, weight)))
    if spec.contact_states:  # a state's readings: its own samples, the same for every a
        Zs = _observations(world, poses, state, weight, S, n_obs)
        Z = np.broadcast_to(Zs, (len(actions), S, n_obs)).copy()
    else:
        Z = np.stack(Z)

    goal = np.bincount(state, weights=weight * in_goal(world, spec, poses), minlength=S)
    R = np.repeat((goal - 1.0)[:, None], len(actions), axis=1)
    R[sentinel] = -1.0

    names = np.array(disc.state_names())[occupied]
    initial = np.zeros(S)
    initial[:np.count_nonzero(occupied[:disc.free_count])] = 1.0
    initial /= initial.sum()
    pomdp = TabularPOMDP(tuple(names.tolist()), spec.action_names,
                         tuple(format(o, f"0{world.sensor_count}b")[::-1] for o in range(n_obs)),
                         tuple(T), Z, R, spec.discount, initial)
    return HandPOMDP(pomdp, disc, kept, spec, world, time.perf_counter() - start)


def _observations(world: PlanarWorld, poses: np.ndarray, state: np.ndarray,
                  weight: np.ndarray, S: int, n_obs: int, *, fallback=None) -> np.ndarray:
    """(S, O) observation probabilities of each state from the readings at ``poses`` (M,
    3) in ``state`` (M,), each pose weighted by ``weight`` (M,): in contact, the true
    reading with probability 1 - e, each other one e / (O - 1); free, no reading. With a
    ``fallback`` (poses, states, weights), each state's row is normalised and a state no
    pose reached takes the fallback's; the sentinel reads nothing."""
    contact, touching = world.sensing.readings(poses)
    key = observation_keys(touching)
    e = world.sensing.error_rate
    wrong = e / (n_obs - 1)
    Zs = np.zeros((S, n_obs))
    np.add.at(Zs, (state[contact], slice(None)), (weight[contact] * wrong)[:, None])
    np.add.at(Zs, (state[contact], key[contact]), weight[contact] * (1 - e - wrong))
    np.add.at(Zs, (state[~contact], 0), weight[~contact])
    if fallback is not None:  # landed poses weigh by their origin: normalise per state
        total = Zs.sum(axis=1)
        seen = total > 0
        Zs[seen] /= total[seen, None]
        Zs[~seen] = _observations(world, *fallback, S, n_obs)[~seen]
    Zs[S - 1] = 0.0
    Zs[S - 1, 0] = 1.0
    return Zs
