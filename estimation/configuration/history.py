"""The predicted belief's exact density for the MPF's dual weights (beyond the thesis).

The thesis weighs each dual particle by the density of the predicted belief b+ at it,
estimated with a Gaussian kernel over the predicted particles (sec. 4.2.3), because b+ is
known only through its samples. In configuration estimation the state is the encoder
offset in disguise (:mod:`models.arms.world`): the arm goes where it is commanded unless a
contact stops it, so a configuration ``q`` now was ``q - (c_t - c_s)`` at step ``s``
(``c`` the commanded configurations), and b+ can be evaluated at any ``q`` without
particles:

    log b+_t(q) = log p0(q - (c_t - c_0)) + sum_{s < t} log p(o_s | q - (c_t - c_s)) + const,

``p0`` the first encoder reading's initial belief (:meth:`ArmWorld.initial_log_density`)
and ``p(o_s | .)`` the contact model of every reading so far. Up to the filter's own
diffusion (which the model adds for the particles' sake, and the true arm does not have)
this is exact. After the first touch the kernel estimate describes a belief that has
collapsed onto a few ancestors (the HERB episode's posterior is far sharper than 100
particles resolve: 5,000 prior draws weighed by every reading keep an effective sample
size below 2), so duals drawn beyond that cluster, where the true configuration may be,
get no weight; the exact density weighs them as the posterior does.

Cost: each dual is evaluated at every past step, ``n_d x t`` configurations per contact
update, batched by reading pattern (at most ``2^S`` calls of the contact model).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.arms.world import ArmWorld

DUAL_DENSITIES = ("kernel", "history")
"""How the MPF evaluates the predicted belief at its duals: ``kernel`` (thesis sec. 4.2.3,
a kernel density of the predicted particles) or ``history`` (this module)."""


def check_dual_density(dual_density: str, metric: str, dual_share: str) -> None:
    """Raise ValueError unless ``dual_density`` is one of :data:`DUAL_DENSITIES`, and the
    ``history`` density comes with the ``joint`` metric (its duals are seeded in balls as
    wide as the prior's spread, which the kernel metric's balls of a few bandwidths of the
    collapsed belief cannot be) and without the ``density`` share (which compares the
    duals' density with a kernel estimate at the conventional particles: two different
    estimates of b+ would be compared)."""
    if dual_density not in DUAL_DENSITIES:
        raise ValueError(f"dual_density must be one of {', '.join(DUAL_DENSITIES)}, got "
                         f"{dual_density!r}")
    if dual_density == "history" and metric != "joint":
        raise ValueError(f"the history dual density seeds its duals in joint-space balls; "
                         f"it needs the joint metric, got {metric!r}")
    if dual_density == "history" and dual_share == "density":
        raise ValueError("the history dual density goes with the fixed or evidence dual "
                         "share, not density (which weighs the conventional set by a kernel "
                         "estimate)")


def dual_ball_radius(world: ArmWorld, dual_density: str,
                     ball_radius_rad: float | None) -> float | None:
    """MPF-Ball's r_b (rad): the given one; else, with the ``history`` density, the
    encoder offset's standard deviation per joint (the arm file's ``offset_sd_rad``: how
    far the truth can lie from a collapsed belief along the joints the readings have not
    pinned down; measured on the HERB episode, 0.05, 0.2 and 0.3 rad all did worse than
    this 0.1); else None (three kernel bandwidths, :class:`ProjectionManifold`)."""
    if ball_radius_rad is not None or dual_density != "history":
        return ball_radius_rad
    return float(world.spec.offset_sd_rad)


@dataclass(frozen=True)
class ReadingHistory:
    """What an estimator has been told since its first encoder reading.

    Attributes:
        encoders: (dof,) the first encoder reading (rad), which gave the initial belief.
        start: (dof,) the commanded configuration then (rad).
        commanded: (k, dof) the commanded configuration at each later reading (rad).
        readings: (k, S) bool, the contact readings (finite ones only: a reading the
            filter left out is not recorded).
    """

    encoders: np.ndarray
    start: np.ndarray
    commanded: np.ndarray
    readings: np.ndarray

    @classmethod
    def begin(cls, encoders: np.ndarray, commanded: np.ndarray, sensors: int
              ) -> ReadingHistory:
        """The history at the first encoder reading ``encoders`` (dof,) rad, commanded
        ``commanded`` (dof,) rad, for ``sensors`` contact sensors."""
        dof = len(encoders)
        return cls(np.array(encoders, dtype=float), np.array(commanded, dtype=float),
                   np.empty((0, dof)), np.empty((0, sensors), dtype=bool))

    def appended(self, commanded: np.ndarray, readings: np.ndarray) -> ReadingHistory:
        """The history with one more step: ``commanded`` (dof,) rad, ``readings`` (S,)."""
        return ReadingHistory(
            self.encoders, self.start,
            np.concatenate([self.commanded, np.asarray(commanded, dtype=float)[None]]),
            np.concatenate([self.readings, np.asarray(readings, dtype=bool)[None]]))

    def log_density(self, world: ArmWorld, states: np.ndarray, commanded: np.ndarray
                    ) -> np.ndarray:
        """(K,) log b+(q) up to a constant (module docstring) at the commanded-side
        configurations ``states`` (K, dof) rad, the arm commanded to ``commanded`` (dof,)
        rad now: the initial belief's density at their start, plus each recorded
        reading's log likelihood at their configuration then."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        commanded = np.asarray(commanded, dtype=float)
        log_p = world.initial_log_density(self.encoders, world.normalise(
            states - (commanded - self.start)[None]))
        if len(self.readings) == 0:
            return log_p
        patterns, which = np.unique(self.readings, axis=0, return_inverse=True)
        which = np.ravel(which)
        for p, pattern in enumerate(patterns):
            steps = np.flatnonzero(which == p)
            past = world.normalise((states[:, None, :] - (
                commanded[None] - self.commanded[steps])[None]).reshape(-1, world.dof))
            log_p = log_p + world.log_likelihood(pattern, past).reshape(
                len(states), len(steps)).sum(axis=1)
        return log_p
