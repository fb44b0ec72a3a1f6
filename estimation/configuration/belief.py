"""From the filter's state to the arm's configuration (see :mod:`models.arms.world`: a
particle is the commanded-side configuration; the arm is where its projection out of
penetration puts it)."""

from __future__ import annotations

import numpy as np

from estimation.particles.belief import ParticleBelief
from models.arms.world import ArmWorld


def configuration_belief(world: ArmWorld, belief: ParticleBelief) -> ParticleBelief:
    """The belief over actual configurations: each particle projected out of penetration,
    with its weight; what the error is measured on and the estimate reported from."""
    return ParticleBelief(world.project_free(np.asarray(belief.states)),
                          np.array(belief.log_weights), belief.angular)
