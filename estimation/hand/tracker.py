"""Tracking the object's pose relative to a moving hand from its measured motion.

The filters of :mod:`estimation.particles.filters` step a belief over object poses in the
hand frame by a hand-frame action. On a robot the hand's motion is measured, not
commanded: between two updates the palm moves from ``A`` to ``B`` (planar world poses),
which is the hand-frame action ``A^-1 B``. :class:`HandRelativeTracker` turns the stream of
(palm pose, sensor reading) pairs into filter updates and remembers whether contact has
been seen, which is what a pre-/post-contact controller switches on (thesis sec. 6.1).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import UpdateDiagnostics, binary_reading
from models.se2 import compose, inverse


class ParticleFilter(Protocol):
    """The CPF or the MPF of :mod:`estimation.particles.filters`."""

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator) -> tuple[ParticleBelief, UpdateDiagnostics]: ...


@dataclass(frozen=True)
class HandRelativeTracker:
    """A particle belief over the object's hand-frame pose, updated from measured motion;
    an immutable value (a system keeps it as Context state), the filter passed in.

    Attributes:
        belief: poses (N, 3) in the hand frame (m, m, rad).
        hand_pose_W: (3,) read-only, the palm's planar world pose when ``belief`` holds.
        contact_seen: has any reading so far reported contact?
        updates: how many updates made this value.
        last_diagnostics: what the last update's filter reported (``None`` before one).
    """

    belief: ParticleBelief
    hand_pose_W: np.ndarray
    contact_seen: bool = False
    updates: int = 0
    last_diagnostics: UpdateDiagnostics | None = None

    def __post_init__(self):
        pose = np.array(self.hand_pose_W, dtype=float)
        pose.setflags(write=False)
        object.__setattr__(self, "hand_pose_W", pose)

    def __deepcopy__(self, memo) -> HandRelativeTracker:
        return self  # immutable: a copy would be the same value

    def update(self, filter: ParticleFilter, hand_pose_W: np.ndarray, reading: np.ndarray, *,
               rng: np.random.Generator) -> HandRelativeTracker:
        """The tracker after the palm moved to ``hand_pose_W`` and took the (S,) boolean
        ``reading`` there: the belief moved by the palm's motion since this value's pose
        and weighed by the reading, through ``filter`` (the CPF or the MPF). A palm pose
        with a NaN or infinity leaves the tracker as it was (its diagnostics say
        ``rejected="action"``), so the next finite pose moves the belief the whole way; a
        reading with one reaches the filter as it is (propagated, not weighed)."""
        hand_pose_W = np.asarray(hand_pose_W, dtype=float)
        if not np.isfinite(hand_pose_W).all():
            return replace(self, updates=self.updates + 1,
                           last_diagnostics=UpdateDiagnostics(False, rejected="action"))
        action = compose(inverse(self.hand_pose_W), hand_pose_W)
        reading = binary_reading(reading)
        finite = reading.dtype == bool
        belief, diagnostics = filter.update(self.belief, action, reading, rng=rng)
        return HandRelativeTracker(belief, hand_pose_W,
                                   self.contact_seen or bool(finite and reading.any()),
                                   self.updates + 1, diagnostics)

    def world_poses(self) -> np.ndarray:
        """(N, 3) the particles as world poses (m, m, rad)."""
        return compose(self.hand_pose_W, np.asarray(self.belief.states))
