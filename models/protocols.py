"""The batched model seams of DESIGN.md, as typing protocols.

Estimators and planners are written against these, not against one world: the planar
hand-relative world (:class:`models.planar.world.PlanarWorld`) answers all three, and so
will a robot-configuration model or a lattice problem. Every method is batched over K
states (particles or scenarios) and deterministic given pre-drawn uniforms, which is what
makes a particle update reproducible from its seed and a DESPOT scenario replayable.
The generative POMDP seam (for DESPOT) is the POMDP library's:
:class:`planning.pomdp.generative.GenerativePOMDP`.

Shapes: ``states (K, d)``; ``action`` one action (an index, or a vector such as a planar
hand motion ``(dx m, dy m, dtheta rad)``); ``u (K, D)`` uniforms in [0, 1); observations
are arrays (for binary contact sensing ``(S,)`` bool for one, ``(K, S)`` for a batch).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class TransitionModel(Protocol):
    """``s' ~ T(s, a)``, batched and deterministic given the uniforms."""

    def uniforms_per_step(self, action: np.ndarray) -> int:
        """D, the uniforms one state's transition consumes under ``action``."""

    def step(self, states: np.ndarray, action: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(K, d) next states of ``states`` (K, d) under ``action`` given ``u`` (K, D)."""

    def sample_step(self, states: np.ndarray, action: np.ndarray, *,
                    rng: np.random.Generator) -> np.ndarray:
        """:meth:`step` with uniforms drawn from ``rng``."""


@runtime_checkable
class ObservationModel(Protocol):
    """``o ~ Z(s', a)`` and its likelihood, batched."""

    def log_likelihood(self, observation: np.ndarray, states: np.ndarray,
                       action: np.ndarray | None = None) -> np.ndarray:
        """(K,) ``log p(observation | state, action)`` of one observation at K states."""

    def sample_observation(self, states: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One observation per state (K, ...) given uniforms ``u``."""


@runtime_checkable
class ContactObservationModel(ObservationModel, Protocol):
    """An observation model of contact sensing, which can also say where contact is
    possible (the MPF restricts no-contact updates to free space, thesis sec. 4.2.4)."""

    def in_contact(self, states: np.ndarray) -> np.ndarray:
        """(K,) bool: would any sensor's geometry touch the object at each state?"""


@runtime_checkable
class FilterModel(TransitionModel, ContactObservationModel, Protocol):
    """What the particle filters of :mod:`estimation.particles.filters` need."""
