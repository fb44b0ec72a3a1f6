"""Tracking the object's pose relative to a moving hand from its measured motion.

The filters of :mod:`estimation.particles.filters` step a belief over object poses in the
hand frame by a hand-frame action. On a robot the hand's motion is measured, not
commanded: between two updates the palm moves from ``A`` to ``B`` (planar world poses),
which is the hand-frame action ``A^-1 B``. :class:`HandRelativeTracker` turns the stream of
(palm pose, sensor reading) pairs into filter updates and remembers whether contact has
been seen, which is what a pre-/post-contact controller switches on (thesis sec. 6.1).
"""

from __future__ import annotations

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import UpdateDiagnostics
from models.se2 import compose, inverse


class HandRelativeTracker:
    """A particle belief over the object's hand-frame pose, updated from measured motion.

    Args:
        filter: anything with ``update(belief, action, observation, *, rng) ->
            (belief, diagnostics)`` (the CPF or the MPF).
        belief: the initial belief (poses (N, 3) in the hand frame: m, m, rad).
        hand_pose_W: (3,) the palm's planar world pose when ``belief`` holds.
    """

    def __init__(self, filter, belief: ParticleBelief, hand_pose_W: np.ndarray):
        self.filter = filter
        self.belief = belief
        self.hand_pose_W = np.asarray(hand_pose_W, dtype=float).copy()
        self.contact_seen = False
        self.updates = 0
        self.last_diagnostics: UpdateDiagnostics | None = None

    def update(self, hand_pose_W: np.ndarray, reading: np.ndarray, *,
               rng: np.random.Generator) -> UpdateDiagnostics:
        """Move the belief by the palm's motion since the last update and weigh it by the
        (S,) boolean ``reading`` taken at ``hand_pose_W``."""
        hand_pose_W = np.asarray(hand_pose_W, dtype=float)
        action = compose(inverse(self.hand_pose_W), hand_pose_W)
        reading = np.asarray(reading, dtype=bool)
        self.belief, diagnostics = self.filter.update(self.belief, action, reading, rng=rng)
        self.hand_pose_W = hand_pose_W.copy()
        self.contact_seen |= bool(reading.any())
        self.updates += 1
        self.last_diagnostics = diagnostics
        return diagnostics

    def world_poses(self) -> np.ndarray:
        """(N, 3) the particles as world poses (m, m, rad)."""
        return compose(self.hand_pose_W, np.asarray(self.belief.states))
