"""Representations of the observable contact manifold that the MPF samples its dual
particles from (thesis sec. 4.2.2; seed 000 sec. 6).

Every representation draws ``n`` states from the dual proposal ``q(s) ~ p(o | s)`` restricted
to the contact manifold (eq. 4.5), through one interface, ``sample(observation, n, *, rng)``:

- :class:`AnalyticManifold` (AM): Minkowski-sum iso-contours every ``dtheta``, cut into
  pieces of at most ``spacing_m``; each piece is labelled with the sensors an object there
  touches; a draw picks a piece with probability proportional to its length times
  ``p(o | piece)`` and a point uniformly along it. This is uniform with respect to the
  manifold's own measure.
- :class:`RejectionSampledManifold` (RS): a fixed set of states drawn uniformly in the
  region around the hand and kept when within ``epsilon`` of both the hand's surface and
  a sensor (seed 000 sec. 6); draws are proportional to ``p(o | s)``.
- :class:`TrajectoryRolloutManifold` (TR): states met on rollouts of the push from the
  initial belief (five per rollout), weighted by ``p(o | s) / p~(s)`` where ``p~`` is a
  kernel density estimate of the set itself, which undoes its concentration in
  frequently visited regions (seed 000 sec. 6, "Trajectory Rollouts").

Labels are the observation model's own noise-free readings, so that a state a
representation offers and the likelihood the filter evaluates always agree.
"""

from __future__ import annotations

import numpy as np

from estimation.particles.kde import log_density
from models.planar.cspace import contact_contour_segments
from models.planar.observation import observation_key, observation_keys
from models.planar.world import PlanarWorld


class KeyedSampler:
    """Draws elements in proportion to ``mass x p(o | element)`` for a reading ``o``.

    Every element (a manifold piece or a stored state) has a non-negative ``mass`` (its
    length, 1, or a density correction) and the key of its noise-free reading. Under the
    observation model, p(o | s) is ``1 - error_rate`` where the key equals o's and
    ``error_rate / (2^S - 1)`` elsewhere, so a draw first picks "matching" or "not" by their
    total weights, then an element by mass within that set (binary search on cumulative
    mass): O(n log N) per draw of n, without touching all N elements.
    """

    def __init__(self, keys: np.ndarray, mass: np.ndarray, error_rate: float,
                 sensor_count: int):
        order = np.argsort(keys, kind="stable")
        self.order = order
        self.keys = keys[order]
        self.cumulative = np.concatenate([[0.0], np.cumsum(mass[order])])
        self.p_match = 1.0 - error_rate
        self.p_wrong = error_rate / (2.0 ** sensor_count - 1.0)

    def draw(self, observation: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
        """Indices (n,) into the original element order."""
        key = observation_key(observation)
        a = int(np.searchsorted(self.keys, key, side="left"))
        b = int(np.searchsorted(self.keys, key, side="right"))
        total = self.cumulative[-1]
        matched = self.cumulative[b] - self.cumulative[a]
        others = total - matched
        w_match, w_other = self.p_match * matched, self.p_wrong * others
        n_match = rng.binomial(n, w_match / (w_match + w_other)) if w_match > 0 else 0
        position = np.empty(n)
        position[:n_match] = self.cumulative[a] + rng.random(n_match) * matched
        rest = rng.random(n - n_match) * others
        position[n_match:] = np.where(rest < self.cumulative[a], rest, rest + matched)
        index = np.searchsorted(self.cumulative, position, side="right") - 1
        return self.order[np.clip(index, 0, len(self.order) - 1)]


class AnalyticManifold:
    """AM: iso-contours of the C-obstacle every ``dtheta_rad`` (thesis: 1 mm, 1.15 deg).

    Attributes:
        starts, ends: (N, 2) piece end points (m); theta: (N,) their orientation (rad);
        keys: (N,) reading keys at the piece midpoints; length: (N,) piece lengths (m).
    """

    def __init__(self, world: PlanarWorld, *, dtheta_rad: float = np.deg2rad(1.15),
                 spacing_m: float = 0.001):
        if not 0 < dtheta_rad <= np.pi / 4 or not 0 < spacing_m <= 0.05:
            raise ValueError("dtheta_rad must be in (0, pi/4] and spacing_m in (0, 0.05]")
        self.world = world
        count = int(round(2 * np.pi / dtheta_rad))
        thetas = -np.pi + 2 * np.pi * np.arange(count) / count
        outline = world.shape.vertices[0][world.shape.valid[0]]
        pieces, angles = [], []
        for theta in thetas:
            seg = contact_contour_segments(world.hand.parts, outline, theta, spacing_m)
            pieces.append(seg)
            angles.append(np.full(len(seg), theta))
        segments = np.concatenate(pieces)
        self.starts, self.ends = segments[:, 0], segments[:, 1]
        self.theta = np.concatenate(angles)
        self.length = np.linalg.norm(self.ends - self.starts, axis=1)
        mid = np.column_stack([(self.starts + self.ends) / 2, self.theta])
        self.keys = observation_keys(world.sensing.true_contacts(mid))
        self.sampler = KeyedSampler(self.keys, self.length, world.sensing.error_rate,
                                    world.sensor_count)

    def __len__(self) -> int:
        return len(self.theta)

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted=None) -> np.ndarray:
        """Draw ``n`` states (n, 3) from the dual proposal for ``observation``."""
        index = self.sampler.draw(observation, n, rng)
        t = rng.random(n)[:, None]
        xy = self.starts[index] + t * (self.ends[index] - self.starts[index])
        return np.column_stack([xy, self.theta[index]])


def contact_region(world: PlanarWorld, margin_m: float) -> np.ndarray:
    """(2, 2) box [[x_lo, y_lo], [x_hi, y_hi]] (m) holding every object centre within
    ``margin_m`` of the hand."""
    verts = world.hand.parts.vertices.reshape(-1, 2)
    reach = world.shape.radii[0] + np.linalg.norm(world.shape.centers[0]) + margin_m
    return np.array([verts.min(0) - reach, verts.max(0) + reach])


class RejectionSampledManifold:
    """RS: ``size`` states uniform in the ambient space, within ``epsilon_m`` of the hand's
    surface and of a sensor (seed 000 sec. 6); fixed once built, reusable across trials."""

    def __init__(self, world: PlanarWorld, *, size: int = 10_000, epsilon_m: float = 0.001,
                 rng: np.random.Generator, batch: int = 200_000, max_batches: int = 500):
        self.world = world
        box = contact_region(world, epsilon_m)
        kept = []
        total = 0
        for _ in range(max_batches):
            s = np.column_stack([rng.uniform(box[0, 0], box[1, 0], batch),
                                 rng.uniform(box[0, 1], box[1, 1], batch),
                                 rng.uniform(-np.pi, np.pi, batch)])
            d = world.sensing.hand_distance(s)
            s = s[np.abs(d) <= epsilon_m]
            near_sensor = world.sensing.true_contacts(s).any(axis=1) if len(s) else []
            kept.append(s[near_sensor])
            total += int(np.sum(near_sensor))
            if total >= size:
                break
        else:
            raise ValueError(f"rejection sampling found only {total} of {size} states")
        self.states = np.concatenate(kept)[:size]
        self.keys = observation_keys(world.sensing.true_contacts(self.states))
        self.sampler = KeyedSampler(self.keys, np.ones(len(self.states)),
                                    world.sensing.error_rate, world.sensor_count)

    def __len__(self) -> int:
        return len(self.states)

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted=None) -> np.ndarray:
        """Draw ``n`` states (n, 3) from the stored set in proportion to p(o | s)."""
        return self.states[self.sampler.draw(observation, n, rng)]


class TrajectoryRolloutManifold:
    """TR: contact states met while rolling the push out from the initial belief.

    Args:
        world: the planar world.
        initial_states: (R, 3) rollout starts drawn from the initial belief.
        action: the hand motion of one update (the straight push's policy).
        updates: number of updates per rollout.
        per_rollout: states kept from each rollout (thesis: 5 from each of 2000).
    """

    def __init__(self, world: PlanarWorld, initial_states: np.ndarray, action: np.ndarray,
                 updates: int, *, per_rollout: int = 5, rng: np.random.Generator):
        self.world = world
        states = np.array(initial_states, dtype=float)
        visited, owner = [], []
        rollout = np.arange(len(states))
        for _ in range(updates):
            states = world.sample_step(states, action, rng=rng)
            touching = world.sensing.true_contacts(states).any(axis=1)
            visited.append(states[touching])
            owner.append(rollout[touching])
        visited_all, owner_all = np.concatenate(visited), np.concatenate(owner)
        # A random ``per_rollout`` of each rollout's contact states.
        shuffled = rng.permutation(len(owner_all))
        grouped = shuffled[np.argsort(owner_all[shuffled], kind="stable")]
        first = np.searchsorted(owner_all[grouped], owner_all[grouped], side="left")
        keep = grouped[np.arange(len(grouped)) - first < per_rollout]
        if len(keep) == 0:
            raise ValueError("no rollout touched a sensor; TR has no states")
        self.states = visited_all[np.sort(keep)]
        self.keys = observation_keys(world.sensing.true_contacts(self.states))
        self.log_density = log_density(self.states, self.states, np.ones(len(self.states)))
        correction = np.exp(self.log_density.min() - self.log_density)  # 1 / p~(s), scaled
        self.sampler = KeyedSampler(self.keys, correction, world.sensing.error_rate,
                                    world.sensor_count)

    def __len__(self) -> int:
        return len(self.states)

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted=None) -> np.ndarray:
        """Draw ``n`` states (n, 3) in proportion to p(o | s) / p~(s)."""
        return self.states[self.sampler.draw(observation, n, rng)]
