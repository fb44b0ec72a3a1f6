"""What the encoders say after their first reading (thesis sec. 3.2 and 5.4.1).

The encoders read ``o_q,t = q_t + dq + eps_t``: the first reading gives the initial belief
(:meth:`models.arms.world.ArmWorld.initial_belief_states`); the constant offset ``dq``
makes the later readings repeat it, so weighing each of them as a reading of ``q_t`` would
count the offset once per step. Their *steps* ``o_q,t - o_q,t-1`` are free of the offset
and say how the arm actually moved: where it was stopped or deflected by a contact, the
encoders show it, also when no sensor reads contact. Weighing the belief by them is this
project's addition (``proprioception="steps"``); the thesis' filters, as this project
first read them, use the first reading alone (``"first"``).
"""

from __future__ import annotations

import numpy as np

from estimation.particles.belief import ParticleBelief
from models.arms.world import ArmWorld

PROPRIOCEPTION = ("first", "steps")
"""What the filters take from the encoders: their first reading alone, or also each step."""


def check_proprioception(proprioception: str) -> None:
    """Raise ValueError unless ``proprioception`` is one of :data:`PROPRIOCEPTION`."""
    if proprioception not in PROPRIOCEPTION:
        raise ValueError(f"proprioception must be one of {', '.join(PROPRIOCEPTION)}, got "
                         f"{proprioception!r}")


def weigh_encoder_step(world: ArmWorld, belief: ParticleBelief, action: np.ndarray,
                       encoder_step: np.ndarray) -> ParticleBelief:
    """The belief after the encoders' step (a second, conditionally independent factor of
    the same time step's observation, applied after the filter's contact update).

    Args:
        world: the arm.
        belief: the posterior over commanded-side configurations after the step's update.
        action: (dof,) the commanded motion of the step (rad).
        encoder_step: (dof,) ``o_q,t - o_q,t-1`` (rad); non-finite: the belief unchanged.

    Returns:
        The belief reweighted by :meth:`ArmWorld.encoder_step_log_likelihood`.
    """
    encoder_step = np.asarray(encoder_step, dtype=float)
    if not np.isfinite(encoder_step).all():
        return belief
    log_w = np.asarray(belief.log_weights) + world.encoder_step_log_likelihood(
        np.asarray(belief.states), action, encoder_step)
    top = log_w.max()
    if not np.isfinite(top):
        return belief
    return ParticleBelief(np.array(belief.states), log_w - top, belief.angular)
