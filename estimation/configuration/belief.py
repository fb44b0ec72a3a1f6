"""From the filter's state to the arm's configuration (see :mod:`models.arms.world`: a
particle is the commanded-side configuration; the arm is where its projection out of
penetration puts it)."""

from __future__ import annotations

import numpy as np

from estimation.particles.belief import ParticleBelief
from models.arms.world import ArmWorld


def joint_rmse(world: ArmWorld, belief: ParticleBelief, q_true: np.ndarray) -> float:
    """The weighted joint-space RMSE (rad) of the belief's configurations against the
    true configuration (thesis sec. 4.3.1): planar joints compared on the circle, the WAM's
    limited joints as they are."""
    linear, angular = configuration_belief(world, belief).rmse(q_true)
    return float(np.hypot(linear, angular))


def configuration_belief(world: ArmWorld, belief: ParticleBelief) -> ParticleBelief:
    """The belief over actual configurations: each particle projected out of penetration,
    with its weight; what the error is measured on and the estimate reported from."""
    return ParticleBelief(world.project_free(np.asarray(belief.states)),
                          np.array(belief.log_weights), belief.angular)
