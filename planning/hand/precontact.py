"""The pre-contact trajectory: weighted A* over no-contact beliefs (thesis sec. 6.3).

Until the sensors fire, every observation is "no contact", so the belief is a deterministic
function of the actions taken and the best open-loop trajectory is a shortest path. A
vertex is ``(b, p_nc, t)``: the belief conditioned on no contact so far (a weighted
particle set), the probability of no contact so far, and the time. Taking action ``a``
gives ``b'(s') ~ W(o_nc | s') T(b, a, s')``, ``p_nc' = p_nc W(o_nc | b', a)``, and costs
(eq. 6.2, sec. 6.3.1)

    c(v, v') = -g^t p_nc (R(b, a) + g sum_{o in O_c} W(o, b', a) V_c[b'_o]),

where ``V_c`` is the post-contact policy's value (max over its vectors) at the posterior
``b'_o`` after contact observation ``o``; the posterior is evaluated on the discrete model
by mapping the particles to their states. The heuristic (sec. 6.3.3) relaxes to full
observability and lets the object pass through the hand:

    h(v) = -g^t p_nc sum_s b(s) Vbar(s),  Vbar(s) = -sum_{k < t_min(s)} g^k,
    t_min(s) = ceil(dist(s, G) / d_max),

an upper bound on value, so ``h`` never overestimates the cost-to-go. Vertices are
ordered by ``f + e_w h`` with ``e_w = 2``. The search stops (sec. 6.4.3) when it expands a
vertex at depth ``H``, one where contact is (almost) certain, one with at least 85 % of the
belief in the trust region (the post-contact policy takes over there), or when the time
limit passes (checked once the root is expanded). It returns the path to the vertex it has
just taken from the frontier: at a stop rule the one that met it, at the time limit the one
it would have expanded next (with an admissible ``h`` the root itself has the smallest
``f + h``, so that is no guide).

One addition to the thesis: vertices reached by the same net hand displacement at the same
time are merged (``merge_duplicates``). Their beliefs differ only through particles that
touched the hand on the way, so this is an approximation; it keeps the search from
expanding every ordering of the same moves.
"""

from __future__ import annotations

import heapq
import time
from dataclasses import dataclass

import numpy as np

from models.planar.observation import observation_keys
from models.settings import check_ranges
from planning.hand.model import HandPOMDP, goal_region
from planning.pomdp.point_based import AlphaVectorPolicy


@dataclass(frozen=True)
class PreContactSettings:
    """Attributes:
        inflation: heuristic inflation e_w (thesis: 2).
        horizon: lookahead depth H (steps).
        time_limit_s: wall-time budget per search (thesis: 20 s).
        trust_mass_stop: stop at a vertex with this much belief in the trust region
            (None: never; the search then runs until contact, the horizon or the time limit).
        contact_stop: stop at a vertex whose no-contact probability is below this.
        merge_duplicates: merge vertices with the same time and net displacement.
    """

    inflation: float = 2.0
    horizon: int = 50
    time_limit_s: float = 20.0
    trust_mass_stop: float | None = 0.85
    contact_stop: float = 1e-3
    merge_duplicates: bool = True

    def __post_init__(self):
        if self.inflation < 1 or self.horizon < 1 or self.time_limit_s <= 0:
            raise ValueError("inflation must be >= 1, horizon >= 1 and time_limit_s > 0")
        check_ranges(self, at_most={"time_limit_s": 3600.0})
        if not 0 <= self.contact_stop <= 1:
            raise ValueError(f"contact_stop must be a probability in [0, 1], got "
                             f"{self.contact_stop}")
        if self.trust_mass_stop is not None and not 0 < self.trust_mass_stop <= 1:
            raise ValueError(f"trust_mass_stop must be in (0, 1] or None, got "
                             f"{self.trust_mass_stop}")


@dataclass(frozen=True)
class PreContactPlan:
    """Attributes:
        actions: the trajectory (action indices).
        cost: its cost f (negated value of its steps).
        expansions: vertices expanded.
        seconds: search wall time (s).
        reason: why the search stopped (``"horizon"``, ``"contact"``, ``"trust_region"``,
            ``"time_limit"``, ``"exhausted"``).
    """

    actions: tuple[int, ...]
    cost: float
    expansions: int
    seconds: float
    reason: str


@dataclass
class _Vertex:
    poses: np.ndarray
    weights: np.ndarray
    p_nc: float
    t: int
    cost: float
    displacement: tuple[int, int]
    actions: tuple[int, ...]


class PreContactPlanner:
    """Weighted A* (see the module docstring).

    Args:
        model: the hand-relative POMDP (its world pushes the particles).
        post_contact: the post-contact policy's vectors (an alpha-vector policy; QMDP's
            ``Q`` columns are vectors too, see :func:`planning.hand.policy.qmdp_vectors`).
        settings: :class:`PreContactSettings`.
    """

    def __init__(self, model: HandPOMDP, post_contact: AlphaVectorPolicy,
                 settings: PreContactSettings = PreContactSettings()):
        self.model = model
        self.vectors = post_contact.alphas
        self.settings = settings
        world = model.world
        self.actions = model.spec.action_vectors()
        self.gamma = model.pomdp.discount
        self.wrong = world.sensing.error_rate / (2.0 ** world.sensor_count - 1.0)
        self.goal = goal_region(world, model.spec)

    def heuristic_values(self, poses: np.ndarray) -> np.ndarray:
        """(N,) Vbar(s): the value upper bound of sec. 6.3.3 (<= 0)."""
        gap = np.maximum(np.maximum(self.goal[0] - poses[:, :2], poses[:, :2] - self.goal[1]),
                         0.0)
        steps = np.ceil(np.linalg.norm(gap, axis=1) / self.model.spec.max_action_m - 1e-9)
        return -(1.0 - self.gamma ** steps) / (1.0 - self.gamma)

    def _h(self, v: _Vertex) -> float:
        return -self.gamma ** v.t * v.p_nc * float(v.weights @ self.heuristic_values(v.poses))

    def _children(self, v: _Vertex, rng: np.random.Generator):
        """The successor of ``v`` under each action, with its edge cost (eq. 6.2)."""
        world, model = self.model.world, self.model
        e = world.sensing.error_rate
        reward = -float(v.weights @ ~model.in_goal(v.poses))
        n_obs = 2 ** world.sensor_count
        for a, action in enumerate(self.actions):
            nxt = world.sample_step(v.poses, action, rng=rng)
            contact, touching = world.sensing.readings(nxt)
            key = observation_keys(touching)
            # weighted p(o | x') for every contact observation o != 0: (O - 1, N)
            joint = np.where(contact[None, :], self.wrong, 0.0) * np.ones((n_obs - 1, 1))
            rows = key[contact] - 1
            hit = rows >= 0
            joint[rows[hit], np.flatnonzero(contact)[hit]] = 1.0 - e
            joint *= v.weights[None, :]
            values = joint @ self.vectors[:, model.index(nxt)].T  # (O - 1, K)
            post = float(values.max(axis=1).sum()) if len(values) else 0.0
            edge = -self.gamma ** v.t * v.p_nc * (reward + self.gamma * post)
            w_nc = v.weights * np.where(contact, np.where(key == 0, 1.0 - e, self.wrong), 1.0)
            total = float(w_nc.sum())
            step = np.round(action[:2] / model.spec.step_m).astype(int)
            yield _Vertex(nxt, w_nc / total if total > 0 else v.weights, v.p_nc * total,
                          v.t + 1, v.cost + edge,
                          (v.displacement[0] + int(step[0]), v.displacement[1] + int(step[1])),
                          v.actions + (a,))

    def plan(self, poses: np.ndarray, weights: np.ndarray | None = None, *,
             rng: np.random.Generator) -> PreContactPlan:
        """Search from the belief given as particles ``poses`` (N, 3) with ``weights``."""
        s = self.settings
        start = time.perf_counter()
        w = np.full(len(poses), 1.0 / len(poses)) if weights is None else weights / weights.sum()
        root = _Vertex(np.asarray(poses, dtype=float), w, 1.0, 0, 0.0, (0, 0), ())
        # ties in priority go to the vertex with the smaller heuristic, then the older one
        frontier = [(s.inflation * self._h(root), self._h(root), 0, root)]
        best_cost: dict[tuple, float] = {}
        counter, expansions, reason = 1, 0, "exhausted"
        v = root
        while frontier:
            _, _, _, v = heapq.heappop(frontier)
            expansions += 1
            if v.t >= s.horizon:
                reason = "horizon"
                break
            if v.p_nc < s.contact_stop:
                reason = "contact"
                break
            if s.trust_mass_stop is not None and float(
                    v.weights @ self.model.discretization.inside(v.poses)) >= s.trust_mass_stop:
                reason = "trust_region"
                break
            if expansions > 1 and time.perf_counter() - start > s.time_limit_s:
                reason = "time_limit"  # v, the vertex it was about to expand, is its best guess
                break
            for child in self._children(v, rng):
                key = (child.t, child.displacement) if s.merge_duplicates else (counter,)
                if child.cost >= best_cost.get(key, np.inf):
                    continue
                best_cost[key] = child.cost
                h_child = self._h(child)
                heapq.heappush(frontier, (child.cost + s.inflation * h_child, h_child, counter,
                                          child))
                counter += 1
        return PreContactPlan(v.actions, v.cost, expansions, time.perf_counter() - start,
                              reason)
