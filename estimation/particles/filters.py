"""The conventional and manifold particle filters (thesis Alg. 4.1 and 4.2).

Both are ``update(belief, action, observation, *, rng) -> (belief, diagnostics)`` over any
batched transition and contact-observation model (:class:`models.protocols.FilterModel`:
the planar hand-relative world, or a robot-configuration model).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.kde import log_density
from estimation.particles.logmath import log_sum_exp
from models.protocols import FilterModel

SAMPLING_FAILURE_LIKELIHOOD = 0.1
"""A dual draw fails when every sample has p(o | s) below this (thesis sec. 4.3.5)."""


class ContactManifold(Protocol):
    """The observable contact manifold of an observation (analytic, rejection-sampled,
    rollout, implicit): the MPF's dual proposal."""

    def sample(self, observation: np.ndarray, n: int, *, rng: np.random.Generator,
               predicted: ParticleBelief | None = None) -> np.ndarray:
        """(n, d) states on the contact manifold of ``observation`` (fewer, even none,
        when the representation fails to find them). ``predicted`` is the prior b+ (the
        propagated particles with their prior weights), which a projection seeds from
        (thesis sec. 5.2: particle and ball projection); other representations ignore it.
        """


@dataclass(frozen=True)
class UpdateDiagnostics:
    """What happened in one filter update.

    Attributes:
        contact_observed: the observation reported contact.
        dual_used: dual particles entered the posterior.
        sampling_failed: every dual sample had p(o | s) < 0.1 (sec. 4.3.5).
        degenerate: no predicted particle could explain the observation (all likelihoods
            zero); the predicted particles kept their prior weights.
    """

    contact_observed: bool
    dual_used: bool = False
    sampling_failed: bool = False
    degenerate: bool = False


def _normalised(log_w: np.ndarray) -> np.ndarray | None:
    total = log_sum_exp(log_w)
    return None if not np.isfinite(total) else log_w - total


class ConventionalParticleFilter:
    """CPF (Alg. 4.1): propagate through the transition model, weight by the observation
    likelihood, resample (low variance) every update.

    Args:
        world: the transition and observation models (e.g. the planar world).
        resample_size: particles after resampling (default: keep the count).
    """

    def __init__(self, world: FilterModel, resample_size: int | None = None):
        self.world = world
        self.resample_size = resample_size

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator) -> tuple[ParticleBelief, UpdateDiagnostics]:
        predicted = self.world.sample_step(np.array(belief.states), action, rng=rng)
        log_w = belief.log_weights + self.world.log_likelihood(observation, predicted, action)
        degenerate = _normalised(log_w) is None
        if degenerate:
            log_w = np.array(belief.log_weights)
        posterior = ParticleBelief(predicted, log_w, belief.angular)
        n = self.resample_size or len(belief)
        return (posterior.resample(n, rng=rng),
                UpdateDiagnostics(bool(np.any(observation)), degenerate=degenerate))


class ManifoldParticleFilter:
    """MPF (Alg. 4.2) with the mixture proposal of sec. 4.2.4.

    Each update: propagate the ``nc`` particles (the CPF's proposal, reused as the predicted
    belief b+); on a contact observation, draw ``nd`` dual particles from the contact
    manifold for that observation (probability of contact 1 for the observed sensors,
    sec. 4.2.1), weight each by the kernel density of b+ at it (sec. 4.2.3), and mix
    ``S = (1 - phi) S_cpf + phi S_dual``; on a no-contact observation,
    ``S = (1 - phi) S_cpf + phi (S_cpf restricted to free space)``. Sets are normalised
    before mixing. When every dual sample has p(o | s) < 0.1 the draw failed (sec. 4.3.5)
    and the update is the CPF's. The posterior is resampled to ``nc`` particles.

    Args:
        world: the transition and observation models (e.g. the planar world).
        manifold: a contact-manifold representation (``sample(observation, n, *, rng)``).
        dual_particles: nd.
        mixing_rate: phi in [0, 1] (0 = CPF, 1 = pure MPF).
    """

    def __init__(self, world: FilterModel, manifold: ContactManifold, *,
                 dual_particles: int = 25, mixing_rate: float = 0.1):
        if not 0.0 <= mixing_rate <= 1.0:
            raise ValueError(f"mixing_rate must be in [0, 1], got {mixing_rate}")
        if dual_particles < 1:
            raise ValueError(f"dual_particles must be >= 1, got {dual_particles}")
        self.world = world
        self.manifold = manifold
        self.dual_particles = dual_particles
        self.mixing_rate = mixing_rate

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator) -> tuple[ParticleBelief, UpdateDiagnostics]:
        phi = self.mixing_rate
        observation = np.asarray(observation, dtype=bool)
        predicted = self.world.sample_step(np.array(belief.states), action, rng=rng)
        prior_w = belief.weights
        cpf = _normalised(belief.log_weights
                          + self.world.log_likelihood(observation, predicted, action))
        contact = bool(observation.any())
        parts_states, parts_log_w = [], []
        failed = dual_used = False
        if contact:
            duals = self.manifold.sample(
                observation, self.dual_particles, rng=rng,
                predicted=ParticleBelief(predicted, belief.log_weights, belief.angular))
            dual_ll = self.world.log_likelihood(observation, duals, action)
            failed = bool(np.all(dual_ll < np.log(SAMPLING_FAILURE_LIKELIHOOD)))
            if not failed:
                dual = _normalised(log_density(duals, predicted, prior_w,
                                               angular=belief.angular))
                if dual is not None:
                    dual_used = True
                    parts_states.append(duals)
                    parts_log_w.append(dual + np.log(phi) if phi > 0 else dual - np.inf)
        elif cpf is not None and phi > 0:
            free = ~self.world.in_contact(predicted)
            restricted = _normalised(np.where(free, cpf, -np.inf))
            if restricted is not None:
                parts_states.append(predicted)
                parts_log_w.append(restricted + np.log(phi))
        degenerate = cpf is None
        if cpf is not None:
            share = 1.0 - phi if parts_states else 1.0
            parts_states.insert(0, predicted)
            parts_log_w.insert(0, cpf + np.log(share) if share > 0 else cpf - np.inf)
        elif not parts_states:  # nothing explains the observation: keep the prediction
            parts_states, parts_log_w = [predicted], [np.log(prior_w)]
        posterior = ParticleBelief(np.concatenate(parts_states), np.concatenate(parts_log_w),
                                   belief.angular)
        diagnostics = UpdateDiagnostics(contact, dual_used, failed, degenerate)
        return posterior.resample(len(belief), rng=rng), diagnostics
