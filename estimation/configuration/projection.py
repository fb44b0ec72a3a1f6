"""Constraint projection onto the implicit contact manifold (thesis sec. 5.1-5.2).

The contact manifold of an observation o is the zero set of
``f_o(q) = [f_i(q) for the active sensors i]`` (eq. 5.1), each ``f_i`` the signed distance of
sensor i to the environment (eq. 5.3), with gradient ``grad F(c)^T J_c(q)`` (eq. 5.4).
A seed is projected by root finding on ``F_o(q) = 1/2 |f_o(q)|^2`` and accepted when every
``|f_i| <= eps_proj``; a seed that does not get there in the iteration budget is a failure.
For an arm that presses into compliant contact (its file's ``press_depth_m`` p > 0) a
touching sensor lies anywhere from p deep to the surface, so ``f_i`` is its distance to
``[-p, 0]`` (zero, with a zero gradient, inside); with p = 0 that is eq. 5.1 itself.

Two root finders, batched over seeds:

- ``gd``, the thesis' gradient descent, ``q <- q - alpha J^T f``. The thesis gives no step
  size; we take ``alpha = 1 / |J|_F^2``, a step no larger than the inverse of the largest
  curvature of ``F_o`` (the largest eigenvalue of ``J^T J``), so the descent never
  overshoots, and needs no tuning across arms of different sizes.
- ``lm``, Levenberg-Marquardt in its minimum-norm form,
  ``q <- q - J^T (J J^T + mu I)^-1 f``: a Gauss-Newton step with ``A = |active|`` rows,
  the smallest joint motion that zeroes the linearised residual (so the seed moves as
  little as possible, which keeps the projected samples near their seeds).

Two constraint sets:

- ``active`` (the thesis, eq. 5.1): only the active sensors' distances. A projected
  sample may leave an inactive sensor touching or a link inside an obstacle, so its
  p(o | s) is that of a wrong reading (with the discriminative sensors of sec. 4.4.1, a
  factor e = 0.001 per such sensor); where a touching link presses its neighbouring
  sensors against the surface too, every dual can fail the sec. 4.3.5 test and the MPF
  falls back on the CPF at every contact step.
- ``full`` (beyond the thesis): the whole reading as constraints, the active sensors'
  distances as equalities and, as one-sided rows ``min(0, d - margin)``, every inactive
  sensor ball clear of the environment by more than the contact tolerance and every body
  ball out of penetration. The rows are hinges: zero (and gradient zero) once satisfied,
  so a sample that already satisfies them moves exactly as under ``active``.

Two metrics for "as little motion as possible" (the step of both root finders):

- joint space, the thesis' (``scale`` None): ``J^T`` as above.
- a diagonal metric ``diag(scale)^-2`` (beyond the thesis; :mod:`estimation.configuration.
  manifold` passes the prior's kernel bandwidths): the steps become ``diag(scale)^2 J^T
  (J diag(scale)^2 J^T + mu I)^-1 f`` and ``alpha diag(scale)^2 J^T f``, so a seed reaches
  the manifold by moving the joints the belief is wide in rather than the ones it is sure
  of, and lands where the prior's kernel density is not negligible.

``cmanip bench configest`` measures both (iterations, failures, time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.arms.world import ArmWorld

METHODS = ("gd", "lm")

CONSTRAINTS = ("active", "full")

EPS_PROJ_M = 0.001
"""Accept a projected sample when every active sensor is within this of the surface (m);
the thesis gives no value: 1 mm, the contact tolerance of the arm files."""

MAX_ITERATIONS = {"gd": 200, "lm": 40}
"""Iteration budgets: gradient descent converges linearly, LM quadratically near a root."""

LM_DAMPING = 1e-4
"""mu (m^2): keeps ``J J^T`` invertible where two active sensors' rows are (nearly)
parallel; without it a step along an ill-conditioned direction can throw a seed far from
where it started (a singular value of 1 cm/rad is damped by half)."""

MAX_STEP_RAD = 0.05
"""Trust region of one root-finding step (rad): a seed moves to the manifold in small
steps rather than one linearised jump."""


@dataclass(frozen=True)
class Projection:
    """Projected samples.

    Attributes:
        states: (K, dof) the projected configurations (rad), successful or not.
        success: (K,) every active sensor within eps_proj of the surface.
        iterations: (K,) iterations each seed took (the budget when it failed).
    """

    states: np.ndarray
    success: np.ndarray
    iterations: np.ndarray


def project(world: ArmWorld, seeds: np.ndarray, active: np.ndarray, *, method: str = "lm",
            eps_proj_m: float = EPS_PROJ_M, max_iterations: int | None = None,
            constraints: str = "active", scale: np.ndarray | None = None) -> Projection:
    """Project seeds (K, dof) onto the manifold of the active sensors.

    Args:
        world: the arm and its environment.
        seeds: (K, dof) configurations (rad).
        active: sorted indices of the active sensors (at least one).
        method: ``gd`` or ``lm``.
        eps_proj_m: acceptance tolerance (m).
        max_iterations: iteration budget (default: :data:`MAX_ITERATIONS`).
        constraints: ``active`` (eq. 5.1) or ``full`` (also the inactive sensors clear
            and the body out of penetration; module docstring).
        scale: (dof,) per-joint lengths (rad) of the step's metric (module docstring;
            None: joint space, the thesis').

    Raises:
        ValueError: an unknown method or constraint set, or no active sensor.
    """
    if method not in METHODS:
        raise ValueError(f"unknown projection method {method!r}; choose from "
                         f"{', '.join(METHODS)}")
    if constraints not in CONSTRAINTS:
        raise ValueError(f"unknown constraint set {constraints!r}; choose from "
                         f"{', '.join(CONSTRAINTS)}")
    active = np.asarray(active, dtype=int)
    if active.size == 0:
        raise ValueError("projection needs at least one active sensor")
    budget = MAX_ITERATIONS[method] if max_iterations is None else max_iterations
    q = world.normalise(np.array(seeds, dtype=float))
    iterations = np.full(len(q), budget)
    running = np.ones(len(q), dtype=bool)
    clear, margin = _clearance_rows(world, active, eps_proj_m, constraints)
    press = world.spec.press_depth_m
    eye = np.eye(len(active) + len(clear))[None]
    # the metric's shape is what steers; its mean is kept at 1 so that the damping mu and
    # the trust region mean what they do in joint space
    metric = np.ones(world.dof) if scale is None else np.asarray(scale, dtype=float) ** 2
    metric = metric / metric.mean()
    for it in range(budget + 1):
        index = np.flatnonzero(running)
        if index.size == 0:
            break
        f, J = world.sensor_distances(q[index], gradient=True, sensors=active)
        if press > 0:  # a pressing arm's sensor touches anywhere in [-press, 0]
            f = f - np.clip(f, -press, 0.0)
            J = J * (f != 0)[..., None]
        done = np.abs(f).max(axis=1) <= eps_proj_m
        if len(clear):
            d, g = world.ball_distances(q[index], gradient=True, balls=clear)
            hinge = np.minimum(d - margin, 0.0)
            done &= (hinge >= -eps_proj_m).all(axis=1)
            f = np.concatenate([f, hinge], axis=1)
            J = np.concatenate([J, g * (hinge < 0)[..., None]], axis=1)
        iterations[index[done]] = it
        running[index[done]] = False
        if it == budget:
            break
        index, f, J = index[~done], f[~done], J[~done]
        MJ = J * metric  # J diag(scale)^2
        if method == "gd":
            alpha = 1.0 / np.maximum((MJ * J).sum(axis=(1, 2)), 1e-12)
            step = -alpha[:, None] * np.einsum("kad,ka->kd", MJ, f)
        else:
            A = np.einsum("kad,kbd->kab", MJ, J) + LM_DAMPING * eye
            step = -np.einsum("kad,ka->kd", MJ, np.linalg.solve(A, f[..., None])[..., 0])
        norm = np.linalg.norm(step, axis=1, keepdims=True)
        step *= np.minimum(1.0, MAX_STEP_RAD / np.maximum(norm, 1e-12))
        q[index] = world.normalise(q[index] + step)
    return Projection(q, ~running, iterations)


def _clearance_rows(world: ArmWorld, active: np.ndarray, eps_proj_m: float,
                    constraints: str) -> tuple[np.ndarray, np.ndarray]:
    """The balls of the one-sided rows of ``full`` and the clearance (m) each must keep:
    the inactive sensors' balls the contact tolerance plus eps_proj (so that they are
    accepted clear of the tolerance), the body's minus the arm's press depth (out of
    penetration, as far as a pressing arm gets out)."""
    if constraints == "active":
        return np.empty(0, dtype=int), np.empty(0)
    owner = world.sensor_of_ball
    clear = np.flatnonzero(~np.isin(owner, active))
    margin = np.where(owner[clear] >= 0, world.spec.contact_tolerance_m + eps_proj_m,
                      -world.spec.press_depth_m)
    return clear, margin
