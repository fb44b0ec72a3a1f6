"""The implicit contact manifold as the MPF's dual proposal: seeds, projected (thesis 5.2).

:class:`ProjectionManifold` answers :class:`estimation.particles.filters.ContactManifold`,
so the manifold particle filter of ch. 4 runs unchanged in configuration space. Each draw
generates seeds by one strategy and projects them (:func:`project`), until ``n``
samples are accepted or ``rounds`` batches of seeds are spent:

- ``uniform``: seeds uniform over the configuration space (the circle for a planar
  joint, the limits for the WAM's): unbiased, but in high dimensions few land where the
  prior is, so most dual samples get negligible weight (particle deprivation).
- ``particle``: the predicted particles S+ themselves, drawn by weight: near the prior,
  but as non-uniform as the particles, and a finite set.
- ``ball``: uniform over the union of balls of radius r_b about the predicted particles,
  R(S+) (sec. 5.2). The thesis chooses r_b "such that the normalized importance weight
  of any particle outside R is sufficiently small"; the dual weight is the kernel density
  of S+, a Gaussian of bandwidth h per joint, so by default r_b = 3 max_j h_j (a point
  farther than r_b from every particle has a kernel weight below e^-4.5 = 1 % of a point on
  a particle). Uniform over the union is exact: a ball picked uniformly, a point uniform
  in it, kept with probability 1 / (the number of balls that cover it).

Two metrics (``metric``), for the balls and for the projection's step:

- ``joint`` (the thesis): balls of radius r_b in joint space, projection by the smallest
  joint motion. The kernel is not isotropic, though: on HERB's WAM after a touch the
  bandwidths of the seven joints differ severalfold, and a ball of 3 times the widest
  reaches 10-30 bandwidths along the narrow joints; measured on the ``wam_fingers`` arm,
  the duals then land 0.2-0.35 rad from every particle, at prior densities e^-15 to
  e^-700 of the particles' own, and the fixed share phi carries them into the belief.
- ``kernel`` (beyond the thesis): the same construction in the kernel's own metric,
  joint j scaled by its bandwidth h_j: ellipsoids of ``BALL_BANDWIDTHS`` bandwidths about
  the particles, and the projection's smallest motion measured in bandwidths
  (:func:`estimation.configuration.projection.project`'s ``scale``), so the duals stay
  where the dual weights (the same kernel density) can tell them apart.

:class:`ExplicitTwoLinkManifold` is the 2-DOF arm's explicit manifold (MPF-Explicit): the
tip sensor's centre on the sphere of radius ``r_obstacle + r_ball`` about the point
obstacle, reached by the elbow-up or the elbow-down configuration; for a point tip on a
point obstacle, exactly those two configurations.

Every draw counts its seeds and failures in :attr:`ProjectionManifold.stats`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from estimation.configuration.projection import CONSTRAINTS, EPS_PROJ_M, METHODS, project
from estimation.particles.belief import ParticleBelief
from estimation.particles.kde import silverman_bandwidth
from models.arms.world import ArmWorld, ball_points
from models.pose import wrap_angle

STRATEGIES = ("uniform", "particle", "ball")

METRICS = ("joint", "kernel")

BALL_BANDWIDTHS = 3.0
"""Default r_b, in kernel bandwidths (the largest joint's)."""


@dataclass
class ProjectionStats:
    """Counts over the draws of one manifold (one filter run).

    Attributes:
        seeds: seeds projected.
        failures: seeds whose projection did not reach eps_proj.
        draws: calls to ``sample`` with contact.
        short_draws: draws that returned fewer samples than asked.
        iterations: total root-finding iterations.
        seconds: wall time spent drawing (s).
    """

    seeds: int = 0
    failures: int = 0
    draws: int = 0
    short_draws: int = 0
    iterations: int = 0
    seconds: float = 0.0

    @property
    def failure_rate(self) -> float:
        """failures / seeds (0 before any seed)."""
        return self.failures / self.seeds if self.seeds else 0.0


@dataclass
class ProjectionManifold:
    """Draws dual particles by seeding and constraint projection.

    Attributes:
        world: the arm and its environment.
        strategy: ``uniform``, ``particle`` or ``ball``.
        method: root finder, ``gd`` (thesis) or ``lm``.
        ball_radius_rad: r_b for ``ball`` (None: :data:`BALL_BANDWIDTHS` bandwidths).
        rounds: batches of ``n`` seeds tried before a draw gives up.
        eps_proj_m: acceptance tolerance (m).
        constraints: ``active`` (eq. 5.1) or ``full`` (:func:`project`).
        metric: ``joint`` (the thesis) or ``kernel`` (module docstring): the metric of
            the balls and of the projection of ``particle`` and ``ball`` seeds.
    """

    world: ArmWorld
    strategy: str = "ball"
    method: str = "lm"
    ball_radius_rad: float | None = None
    rounds: int = 3
    eps_proj_m: float = EPS_PROJ_M
    constraints: str = "active"
    metric: str = "joint"
    stats: ProjectionStats = field(default_factory=ProjectionStats)

    def __post_init__(self):
        if self.strategy not in STRATEGIES:
            raise ValueError(f"unknown projection strategy {self.strategy!r}; choose from "
                             f"{', '.join(STRATEGIES)}")
        if self.rounds < 1:
            raise ValueError(f"rounds must be >= 1, got {self.rounds}")
        if self.method not in METHODS:
            raise ValueError(f"unknown projection method {self.method!r}; choose from "
                             f"{', '.join(METHODS)}")
        if self.ball_radius_rad is not None and not self.ball_radius_rad > 0:
            raise ValueError(f"ball_radius_rad must be > 0, got {self.ball_radius_rad}")
        if self.constraints not in CONSTRAINTS:
            raise ValueError(f"unknown constraint set {self.constraints!r}; choose from "
                             f"{', '.join(CONSTRAINTS)}")
        check_metric(self.metric, self.ball_radius_rad)

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted: ParticleBelief | None = None) -> np.ndarray:
        """Up to ``n`` configurations (n', dof) on the manifold of ``observation``.

        Raises:
            ValueError: ``particle`` or ``ball`` without the predicted belief.
        """
        active = np.flatnonzero(np.asarray(observation, dtype=bool))
        if active.size == 0:
            return np.empty((0, self.world.dof))
        if self.strategy != "uniform" and predicted is None:
            raise ValueError(f"{self.strategy} projection seeds from the predicted belief")
        self.stats.draws += 1
        start = time.perf_counter()
        accepted = []
        scale = (self.bandwidth(predicted) if self.metric == "kernel"
                 and self.strategy != "uniform" else None)
        for _ in range(self.rounds):
            seeds = self.seeds(n, predicted, rng=rng, scale=scale)
            result = project(self.world, seeds, active, method=self.method,
                             eps_proj_m=self.eps_proj_m, constraints=self.constraints,
                             scale=scale)
            self.stats.seeds += len(seeds)
            self.stats.failures += int((~result.success).sum())
            self.stats.iterations += int(result.iterations.sum())
            accepted.append(result.states[result.success])
            if sum(len(a) for a in accepted) >= n:
                break
        states = np.concatenate(accepted)[:n]
        self.stats.short_draws += int(len(states) < n)
        self.stats.seconds += time.perf_counter() - start
        return states

    def seeds(self, n: int, predicted: ParticleBelief | None, *,
              rng: np.random.Generator, scale: np.ndarray | None = None) -> np.ndarray:
        """(n, dof) seeds by the strategy; ``scale`` (dof,): the kernel metric's
        bandwidths (rad), None for the joint metric."""
        world = self.world
        if self.strategy == "uniform":
            if world.model.continuous:
                return rng.uniform(-np.pi, np.pi, (n, world.dof))
            return rng.uniform(world.lower, world.upper, (n, world.dof))
        states = np.asarray(predicted.states)
        if self.strategy == "particle":
            return states[rng.choice(len(states), n, p=predicted.weights)]
        if scale is not None:
            return union_of_balls(states, BALL_BANDWIDTHS, n, rng=rng,
                                  wrap=world.model.continuous, scale=scale)
        radius = self.ball_radius(predicted)
        return union_of_balls(states, radius, n, rng=rng, wrap=world.model.continuous)

    def ball_radius(self, predicted: ParticleBelief) -> float:
        """r_b (rad) of the joint metric: the fixed value, or 3 of the prior's widest
        kernel bandwidths."""
        if self.ball_radius_rad is not None:
            return self.ball_radius_rad
        return float(BALL_BANDWIDTHS * self.bandwidth(predicted).max())

    @staticmethod
    def bandwidth(predicted: ParticleBelief) -> np.ndarray:
        """(dof,) the prior's kernel bandwidths (rad; Silverman's, as the dual weights')."""
        return silverman_bandwidth(np.asarray(predicted.states), predicted.weights,
                                   predicted.angular)


def check_metric(metric: str, ball_radius_rad: float | None) -> None:
    """Raise ValueError unless ``metric`` is one of :data:`METRICS` and a fixed r_b comes
    only with the joint metric (the kernel metric's balls are three bandwidths)."""
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose from {', '.join(METRICS)}")
    if metric == "kernel" and ball_radius_rad is not None:
        raise ValueError("the kernel metric's balls are BALL_BANDWIDTHS bandwidths: "
                         "ball_radius_rad is for the joint metric")


def union_of_balls(centers: np.ndarray, radius: float, n: int, *,
                   rng: np.random.Generator, wrap: bool,
                   scale: np.ndarray | None = None) -> np.ndarray:
    """(n, d) points uniform over the union of balls of ``radius`` about ``centers``
    (N, d): a ball picked uniformly, a point uniform in it, kept with probability one over
    the number of balls covering it (differences wrapped on the circle when ``wrap``).
    With ``scale`` (d,), the balls are of the metric that divides coordinate j by
    ``scale[j]`` (ellipsoids of half-axes ``radius * scale``)."""
    centers = np.unique(centers, axis=0)
    d = centers.shape[1]
    scale = np.ones(d) if scale is None else np.asarray(scale, dtype=float)
    out = []
    while sum(len(o) for o in out) < n:
        k = max(n, 16)
        points = centers[rng.integers(len(centers), size=k)] + scale * ball_points(
            rng.random((k, d + 1)), radius)
        diff = points[:, None, :] - centers[None]
        if wrap:  # by rint, not wrap_angle's float modulo (six times slower at this size)
            diff -= (2.0 * np.pi) * np.rint(diff * (0.5 / np.pi))
        diff = diff / scale
        cover = (np.einsum("kni,kni->kn", diff, diff) <= radius * radius).sum(axis=1)
        keep = rng.random(k) * np.maximum(cover, 1) < 1.0
        out.append(wrap_angle(points[keep]) if wrap else points[keep])
    return np.concatenate(out)[:n]


class ExplicitTwoLinkManifold:
    """MPF-Explicit for a 2-link planar arm whose one sensor is a ball at its tip and whose
    world is one sphere (a point when its radius is 0): the tip centre is drawn uniformly
    on the circle of radius ``r_obstacle + r_ball`` about the obstacle's centre, then
    reached by the elbow-up or elbow-down configuration with equal probability.

    Raises:
        ValueError: an arm or world of another shape.
    """

    def __init__(self, world: ArmWorld):
        spec = world.spec
        env = world.environment
        tip = spec.sensors[0].balls[0] if len(spec.sensors) == 1 else None
        if (spec.kind != "planar" or len(spec.links_m) != 2 or tip is None
                or len(spec.sensors[0].balls) != 1 or tip.link != "link_1"
                or abs(tip.center_m[0] - spec.links_m[1]) > 1e-12
                or len(env.sphere_radii) != 1 or len(env.box_half) or len(env.cyl_radii)):
            raise ValueError("the explicit manifold is the 2-link arm's with one tip sensor "
                             "and one point (sphere) obstacle")
        self.links = spec.links_m
        self.center = env.sphere_centers[0, :2]
        self.radius = float(env.sphere_radii[0] + tip.radius_m)
        self.stats = ProjectionStats()

    def configurations(self, tips: np.ndarray, elbow_up: np.ndarray) -> np.ndarray:
        """(K, 2) joint angles (rad) that put the tip at ``tips`` (K, 2) m, on the branch
        of positive (``elbow_up``) or negative elbow angle; NaN where out of reach."""
        l0, l1 = self.links
        r2 = (tips ** 2).sum(axis=1)
        cos_elbow = (r2 - l0 * l0 - l1 * l1) / (2 * l0 * l1)
        elbow = np.where(elbow_up, 1.0, -1.0) * np.arccos(np.where(
            np.abs(cos_elbow) <= 1.0, cos_elbow, np.nan))
        shoulder = np.arctan2(tips[:, 1], tips[:, 0]) - np.arctan2(
            l1 * np.sin(elbow), l0 + l1 * np.cos(elbow))
        return wrap_angle(np.column_stack([shoulder, elbow]))

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted: ParticleBelief | None = None) -> np.ndarray:
        """Up to ``n`` configurations with the tip on the obstacle (none without contact)."""
        if not np.asarray(observation, dtype=bool).any():
            return np.empty((0, 2))
        angle = rng.uniform(-np.pi, np.pi, n)
        tips = self.center + self.radius * np.column_stack([np.cos(angle), np.sin(angle)])
        q = self.configurations(tips, rng.random(n) < 0.5)
        ok = np.isfinite(q).all(axis=1)
        self.stats.draws += 1
        self.stats.seeds += n
        self.stats.failures += int((~ok).sum())
        return q[ok]
