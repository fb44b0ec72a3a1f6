"""The policies of thesis sec. 7.3.2 over the configuration lattice.

- :class:`LiftPolicy`: Lift-QMDP and Lift-SARSOP: a hand-relative policy's choice, replaced
  by the feasible action of next highest value when the lattice says it is infeasible (the
  lattice asked in order of value, lazily).
- :class:`LatDespotPlanner`: Lat-DESPOT, DESPOT on Lat-POMDP
  (:class:`~planning.lattice.pomdp.LatticePOMDP`) with Rel-QMDP as upper bound and
  Lift-QMDP rollouts as lower bound (thesis sec. 7.2), or with the point-based solver's
  bounds (the model's ``upper_values`` and ``rollout_policy``; sec. 7.4's missing piece).

Both answer the ``Planner`` protocol: ``plan(belief, *, rng, point=, palm_pose=, ...)``,
the robot's lattice point given directly or as the palm's planar world pose (which must
lie on the lattice, within :data:`ON_LATTICE_M`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from estimation.particles.belief import ParticleBelief
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.pomdp import LatticePOMDP, lift_choice
from planning.pomdp.despot import DespotSettings
from planning.pomdp.online import DespotMemory, DespotPlanner
from planning.pomdp.point_based import AlphaVectorPolicy
from planning.protocols import PlanResult

#: How far (m) a palm pose may lie from its lattice point.
ON_LATTICE_M = 0.001


def check_budget(trials: int | None, seconds: float) -> None:
    """Refuse a Lat-DESPOT budget other than ``trials`` >= 1 (or None: the wall-clock cap
    alone) per decision with a cap of ``seconds`` > 0.

    Raises:
        ValueError: naming the bad value.
    """
    if trials is not None and trials < 1:
        raise ValueError(f"lat_despot_trials must be >= 1 or None, got {trials}")
    if not seconds > 0:
        raise ValueError(f"lat_despot_seconds must be > 0 s, got {seconds}")


def lattice_point(lattice: ConfigurationLattice, *, point: int | None = None,
                  palm_pose: np.ndarray | None = None) -> int:
    """The robot's lattice point, given as ``point`` or as the palm's world pose (3,).

    Raises:
        ValueError: neither given, or the palm is off the lattice.
    """
    if point is not None:
        return int(point)
    if palm_pose is None:
        raise ValueError("a lattice planner needs the robot's lattice point (point=) or the "
                         "palm's pose (palm_pose=)")
    nearest, distance = lattice.spec.nearest_point(palm_pose)
    if nearest < 0:
        raise ValueError(f"the palm at {np.round(palm_pose[:2], 4).tolist()} m is off the "
                         "lattice")
    if distance > ON_LATTICE_M:
        raise ValueError(f"the palm at {np.round(palm_pose[:2], 4).tolist()} m is "
                         f"{distance * 1e3:.1f} mm from the nearest lattice point")
    return nearest


def lifted_ranking(values: np.ndarray, feasible: np.ndarray) -> tuple[int, ...]:
    """Actions in order of ``values`` (A,), the feasible (A,) bool ones first."""
    order = np.argsort(-values, kind="stable")
    return tuple(int(a) for a in (*order[feasible[order]], *order[~feasible[order]]))


class LiftPolicy:
    """Lift-QMDP or Lift-SARSOP (see the module docstring) on a discrete belief.

    Args:
        vectors: the hand-relative policy (Rel-QMDP's Q as vectors, or Rel-SARSOP's).
        lattice: the scene's lattice.
    """

    phase = "lift"

    def __init__(self, vectors: AlphaVectorPolicy, lattice: ConfigurationLattice):
        self.vectors = vectors
        self.lattice = lattice

    def act(self, point: int, belief: np.ndarray) -> int:
        """The lifted choice at lattice point ``point`` for the discrete belief (S,)."""
        values = self.vectors.action_values(belief)[None]
        return int(lift_choice(values, lambda rows, actions: self.lattice.feasible(
            np.full(len(rows), point), actions))[0])

    def plan(self, belief: np.ndarray, *, rng: np.random.Generator, point: int | None = None,
             palm_pose: np.ndarray | None = None, **context) -> PlanResult:
        start = time.perf_counter()
        point = lattice_point(self.lattice, point=point, palm_pose=palm_pose)
        action = self.act(point, belief)
        values = self.vectors.action_values(belief)
        feasible = self.lattice.feasible_actions(point)  # the fallback order: all of them
        ranking = (action, *[a for a in lifted_ranking(values, feasible) if a != action])
        return PlanResult(action, ranking, self.phase, (time.perf_counter() - start) * 1e3)


@dataclass(frozen=True)
class LatDespotMemory:
    """Lat-DESPOT's memory between decisions: DESPOT's (for subtree reuse)."""

    despot: DespotMemory = DespotMemory()


class LatDespotPlanner:
    """Lat-DESPOT behind the ``Planner`` protocol.

    ``plan(belief, *, rng, point=, palm_pose=, memory=, observation=)``: ``belief`` is a
    :class:`~estimation.particles.belief.ParticleBelief` of hand-frame object poses (the
    estimator's; DESPOT's scenarios are drawn from its particles), or an (N, d) array of
    the model's inner states (cells (N, 1) of the discrete model). Its statistics add the
    lattice's: ``lattice_edges_evaluated`` (by this decision) and
    ``lattice_edge_fraction`` (of the whole lattice, so far).

    Args:
        pomdp: Lat-POMDP of the scene (its bounds are the planner's).
        settings: DESPOT's settings.
    """

    phase = "lat-despot"

    def __init__(self, pomdp: LatticePOMDP, settings: DespotSettings | None = None):
        self.pomdp = pomdp
        self.lattice = pomdp.lattice
        self.despot = DespotPlanner(pomdp, settings or DespotSettings())

    def plan(self, belief, *, rng: np.random.Generator, point: int | None = None,
             palm_pose: np.ndarray | None = None, memory: LatDespotMemory | None = None,
             observation: int | None = None, **context) -> PlanResult:
        start = time.perf_counter()
        point = lattice_point(self.lattice, point=point, palm_pose=palm_pose)
        weights = None
        if isinstance(belief, ParticleBelief):
            weights = np.exp(belief.log_weights - belief.log_weights.max())
            rows = self.pomdp.from_poses(point, belief.states)
        else:
            rows = self.pomdp.with_point(point, np.asarray(belief))
        before = self.lattice.stats().edges_evaluated
        memory = memory or LatDespotMemory()
        result = self.despot.plan(rows, rng=rng, weights=weights, memory=memory.despot,
                                  observation=observation)
        lattice = self.lattice.stats()
        stats = {**result.stats, "lattice_edges_evaluated": lattice.edges_evaluated - before,
                 "lattice_edge_fraction": lattice.edge_fraction}
        return replace(result, phase=self.phase, stats=stats,
                       planning_ms=(time.perf_counter() - start) * 1e3,
                       memory=LatDespotMemory(result.memory))
