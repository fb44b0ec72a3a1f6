"""Dual particles lifted from the contact surface to the commanded side (beyond the thesis).

The thesis' dual particles are points of the contact manifold: configurations whose
active sensors touch (sec. 5.2). Here a particle is the *commanded-side* configuration
(:mod:`models.arms.world`): while the arm presses on an obstacle, the state lies beyond
the surface, and every configuration on the path behind a surface point ``d`` that the
projection out of penetration would bring back to ``d`` reads the same contact now. The
projection (:meth:`ArmWorld.project_free`) steps along the penetrating balls' distance
gradients, so that path is traced backwards by following the contact normal into the
obstacle as it turns: ``dq/ds = u(q)``, ``u`` the unit joint motion that drives the active
sensors deeper (on the 2-DOF arm at a pressed truth 0.023 rad behind the surface, the
traced path passes within 0.0013 rad of the truth, the straight ray along the normal at
``d`` only within 0.012). Those states differ in their past, though: a state deeper
behind the surface was as much farther along when the contact began, and at every earlier
touch. Weighed as the commanded side, a
surface dual near a pressed truth has the history of a state that touched later than the
arm did and missed its earlier touches; measured on the 2-DOF arm under the history
density (``experiment configest --arm 2dof --dual-density history``, trial 2, step 481),
the true actual configuration scores log b+ = -21 against -0.2 at the true state, and
the duals nearest the truth -304, as low as duals on the wrong elbow branch. The fixed
share phi then spreads over all of them, a tenth of the belief lands on the other branch,
and the error jumps from 0.05 to 0.75 rad.

:class:`NormalLift` maps each dual to the point of its path, from the surface (depth 0,
the thesis' dual, always a candidate) to :data:`MAX_DEPTH_RAD`, at which the dual density
the filter weighs with is largest, on a grid of :data:`DEPTHS` depths (``normal``);
``normal-refined`` then bisects around the grid's best down to the traced path's step
:data:`FLOW_STEP_RAD`. The grid costs the lift's precision: on the 2-DOF arm's experiment
2, MPF-Particle ends at 0.050 rad with the grid, 0.037 with 41 grid depths (0.0025 rad
apart), 0.022 without the lift. The bisection does not recover it: over the 2-DOF study's
10 experiments under the history density every variant ends at 0.048-0.049 rad with
either (MPF-Particle's final error refined minus grid +0.000 +- 0.004, paired, 95 %), at
16 min against 12.5 (measured 2026-12-07, 2 workers), so the grid is the default and the
bisection stays selectable for the comparison. Where the density is flat along the path
(every reading explained over a stretch of depths), drawing the depth in proportion to
the density instead of taking its largest value changed nothing either (0.050 and 0.051
on experiments 2 and 3, against 0.050 and 0.049; not kept).
The lift is a deterministic map of the dual, so the duals' proposal density is the
manifold's carried along the map; the map's Jacobian is taken as one (the weights are
b+ at the lifted duals, as for the surface duals): an approximation.

Cost: :data:`DEPTHS` evaluations of the dual density per dual instead of one (and four
more for the bisection), each over the whole history with the history density, deeper
candidates costing more (their past configurations lie deeper inside the obstacle, and
projecting them out takes more iterations: ``bench configest``'s
``lift_cost_ratio_to_density``, 17.5 for the grid alone at the 2-DOF run's end): the
2-DOF study of 10 experiments under the
history density took 12.5 min with the lift against 1.5 min without (measured 2026-12-07,
2 workers).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from models.arms.world import ArmWorld

DUAL_LIFTS = ("surface", "normal", "normal-refined")
"""Where the MPF's duals sit: ``surface`` (the thesis: the manifold's points), ``normal``
(lifted along the contact normal to the best of a grid of depths, :class:`NormalLift`) or
``normal-refined`` (the same, then bisected around the grid's best depth)."""

MAX_DEPTH_RAD = 0.1
"""The deepest candidate behind the surface (joint-space norm, rad): how far the commanded
side can lie beyond the contact, the trajectory's press (0.023 rad measured on the 2-DOF
arm's second touch)."""

DEPTHS = 11
"""Candidates per dual, evenly from the surface to :data:`MAX_DEPTH_RAD` (steps of 0.01 rad:
at the 2-DOF arm's 0.25 m distal link, 2.5 mm of tip motion, within a grid step of the
1 mm contact tolerance)."""

FLOW_STEP_RAD = 0.0025
"""The step (rad) of the traced path between candidates (a grid step's quarter)."""

NORMAL_DAMPING = 1e-6
"""mu (m^2) of ``J J^T + mu I`` in the lift's direction (rows of two active sensors can be
parallel)."""


def check_dual_lift(dual_lift: str) -> None:
    """Raise ValueError unless ``dual_lift`` is one of :data:`DUAL_LIFTS`."""
    if dual_lift not in DUAL_LIFTS:
        raise ValueError(f"dual_lift must be one of {', '.join(DUAL_LIFTS)}, got "
                         f"{dual_lift!r}")


def make_dual_lift(world: ArmWorld, dual_lift: str) -> NormalLift | None:
    """The MPF's ``dual_lift`` for the setting ``dual_lift`` (one of :data:`DUAL_LIFTS`):
    None for ``surface`` (the thesis), :class:`NormalLift` otherwise."""
    check_dual_lift(dual_lift)
    if dual_lift == "surface":
        return None
    return NormalLift(world, refine=dual_lift == "normal-refined")


@dataclass(frozen=True)
class NormalLift:
    """Lifts duals along their contact normals to the depth the dual density favours
    (module docstring); the MPF's ``dual_lift``.

    Attributes:
        world: the arm and its environment.
        max_depth_rad: the deepest candidate (rad).
        depths: grid candidates per dual, the surface included.
        refine: bisect around the best grid depth down to one traced step (measured no
            better at 2-DOF, module docstring).
    """

    world: ArmWorld
    max_depth_rad: float = MAX_DEPTH_RAD
    depths: int = DEPTHS
    refine: bool = False

    def __post_init__(self):
        if not self.max_depth_rad > 0 or self.depths < 2:
            raise ValueError(f"the lift needs max_depth_rad > 0 and depths >= 2, got "
                             f"{self.max_depth_rad} and {self.depths}")

    def directions(self, duals: np.ndarray, active: np.ndarray) -> np.ndarray:
        """(K, dof) unit joint motions (rad/rad) that drive every active sensor deeper at
        the same rate: ``-J^T (J J^T + mu I)^-1 1``, the smallest such motion, normalised
        (one sensor: minus its distance gradient, eq. 5.4)."""
        _, J = self.world.sensor_distances(duals, gradient=True, sensors=active)
        A = np.einsum("kad,kbd->kab", J, J) + NORMAL_DAMPING * np.eye(len(active))[None]
        rates = np.linalg.solve(A, np.ones((len(duals), len(active), 1)))[..., 0]
        u = -np.einsum("kad,ka->kd", J, rates)
        return u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)

    @property
    def substeps(self) -> int:
        """Traced steps between neighbouring grid depths (of at most :data:`FLOW_STEP_RAD`)."""
        return max(1, int(np.ceil(self.max_depth_rad / (self.depths - 1) / FLOW_STEP_RAD
                                  - 1e-9)))

    def __call__(self, duals: np.ndarray, observation: np.ndarray,
                 log_density: Callable[[np.ndarray], np.ndarray]
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The lifted duals (K, dof) rad and the dual density's log at them (K,).

        The grid's :data:`DEPTHS` depths first, then (with ``refine``) a bisection around
        each dual's best grid depth, halving the offset down to one traced step: two more
        evaluations per halving.

        Args:
            duals: (K, dof) configurations on the manifold of ``observation`` (rad).
            observation: (S,) the contact reading they were drawn for.
            log_density: (M, dof) -> (M,) the predicted belief's log density (up to a
                constant), the one the filter weighs its duals with.
        """
        duals = np.atleast_2d(np.asarray(duals, dtype=float))
        active = np.flatnonzero(np.asarray(observation, dtype=bool))
        if len(duals) == 0 or active.size == 0:
            return duals, log_density(duals)
        traced = self.path(duals, active)  # (F, K, dof)
        rows, dof = np.arange(len(duals)), duals.shape[1]
        grid = np.arange(0, len(traced), self.substeps)
        values = log_density(traced[grid].reshape(-1, dof)).reshape(len(grid), len(duals))
        best = np.argmax(values, axis=0)
        index, value = grid[best], values[best, rows]
        offset = self.substeps // 2 if self.refine else 0
        while offset >= 1:
            for side in (-offset, offset):
                near = index + side
                inside = np.flatnonzero((near >= 0) & (near < len(traced)))
                there = log_density(traced[near[inside], inside])
                better = there > value[inside]
                index[inside[better]], value[inside[better]] = near[inside[better]], \
                    there[better]
            offset //= 2
        return traced[index, rows], value

    def path(self, duals: np.ndarray, active: np.ndarray) -> np.ndarray:
        """(F, K, dof) each dual's path into the obstacle (module docstring), traced by
        :attr:`substeps` steps along :meth:`directions` between neighbouring grid depths:
        F = (depths - 1) substeps + 1 points from depth 0 to ``max_depth_rad`` (rad), the
        grid depths every ``substeps``-th."""
        substeps = self.substeps
        spacing = self.max_depth_rad / (self.depths - 1) / substeps
        q = duals.copy()
        out = [q]
        for _ in range((self.depths - 1) * substeps):
            q = self.world.normalise(q + spacing * self.directions(q, active))
            out.append(q)
        return np.stack(out)
