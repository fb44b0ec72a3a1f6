"""The conventional and manifold particle filters (thesis Alg. 4.1 and 4.2).

Both are ``update(belief, action, observation, *, rng) -> (belief, diagnostics)`` over any
batched transition and contact-observation model (:class:`models.protocols.FilterModel`:
the planar hand-relative world, or a robot-configuration model).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Protocol

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.kde import leave_one_out_log_density, log_density
from estimation.particles.logmath import log_sum_exp
from models.protocols import FilterModel

SURPRISE = 1e-3
"""A reading whose evidence p(o | b+) is below this surprises the belief (a caller may
flag it; :attr:`UpdateDiagnostics.log_evidence`)."""

DualLift = Callable[[np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]],
                    tuple[np.ndarray, np.ndarray]]
"""The MPF's optional map from manifold samples to the states they stand for
(:class:`ManifoldParticleFilter`'s ``dual_lift``)."""

SAMPLING_FAILURE_LIKELIHOOD = 0.1
"""A dual draw fails when every sample has p(o | s) below this (thesis sec. 4.3.5)."""

DUAL_SHARES = ("fixed", "density", "evidence")
"""How the MPF splits the posterior between its two sets: ``fixed`` (Alg. 4.2, phi to the
duals whatever they are), ``density`` (phi scaled down when the duals sit where the
prior is thinner than under the conventional set's posterior) or ``evidence`` (phi scaled
by the share of the reading the prior fails to explain); see the MPF's docstring."""

DENSITY_PROBES = 256
"""Posterior particles of the conventional set at which the ``density`` share evaluates
the prior (a Q x N kernel sum, so Q stays bounded when N is large)."""


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
        log_evidence: log p(o | b+) = log sum_i w_i p(o | s_i) over the predicted
            particles, the reading's marginal likelihood under the prediction (0 when no
            reading was weighed); a reading far less likely than usual is a surprise a
            caller can flag (-inf: degenerate).
        rejected: ``""``, or the input that was not used: ``"action"`` (not finite: the
            update was skipped, the belief kept as it was), ``"observation"`` (not
            finite) or ``"outlier"`` (its evidence below the filter's outlier gate); for
            both of these the belief was propagated and not weighted.
    """

    contact_observed: bool
    dual_used: bool = False
    sampling_failed: bool = False
    degenerate: bool = False
    log_evidence: float = 0.0
    rejected: str = ""


def non_finite_input(action: np.ndarray, observation: np.ndarray) -> str:
    """Which input of an update holds a NaN or infinity: ``"action"``, ``"observation"``
    or ``""``. A sensor driver's dropout or a bad transform arrives as such a value; a
    filter that used it would turn every particle into NaN, so it is reported and left
    out instead (a reading is checked only when it is numeric: booleans are finite)."""
    if not np.all(np.isfinite(np.asarray(action, dtype=float))):
        return "action"
    reading = np.asarray(observation)
    if reading.dtype.kind in "fc" and not np.all(np.isfinite(reading)):
        return "observation"
    return ""


def binary_reading(values: np.ndarray) -> np.ndarray:
    """(S,) contact readings from sensor values (> 0.5 is contact) as booleans, or, when
    any value is NaN or infinite, the values themselves as floats, which the filters
    recognise and leave out (a threshold would read NaN as "no contact")."""
    values = np.asarray(values)
    if values.dtype.kind in "fc" and not np.all(np.isfinite(values)):
        return values.astype(float)
    return values > 0.5


def _unweighted(belief: ParticleBelief, predicted: np.ndarray, rejected: str,
                log_evidence: float = 0.0) -> tuple[ParticleBelief, UpdateDiagnostics]:
    """The update when the reading was not used: the prediction with the prior weights."""
    return (ParticleBelief(predicted, np.array(belief.log_weights), belief.angular),
            UpdateDiagnostics(False, log_evidence=log_evidence, rejected=rejected))


def _predict(world: FilterModel, belief: ParticleBelief, action: np.ndarray,
             observation: np.ndarray, rng: np.random.Generator):
    """The predicted particles (N, d), or, when an input is not finite, the update's
    result instead: the belief as it was (the action) or its unweighted prediction (the
    reading). Returns ``(predicted, None)`` or ``(None, result)``."""
    rejected = non_finite_input(action, observation)
    if rejected == "action":
        return None, (belief, UpdateDiagnostics(False, rejected=rejected))
    predicted = world.sample_step(np.array(belief.states), action, rng=rng)
    if rejected:
        return None, _unweighted(belief, predicted, rejected)
    return predicted, None


def _check_gate(outlier_log_evidence: float | None) -> None:
    if outlier_log_evidence is not None and not outlier_log_evidence < 0:
        raise ValueError(f"outlier_log_evidence must be < 0 or None, got "
                         f"{outlier_log_evidence}")


def _log_evidence(belief: ParticleBelief, log_w: np.ndarray) -> float:
    """log sum_i w_i p(o | s_i) from the weighted log-likelihoods ``log_w`` (the belief's
    log-weights plus each particle's log-likelihood)."""
    return float(log_sum_exp(log_w) - log_sum_exp(np.asarray(belief.log_weights)))


def _normalised(log_w: np.ndarray) -> np.ndarray | None:
    total = log_sum_exp(log_w)
    return None if not np.isfinite(total) else log_w - total


class ConventionalParticleFilter:
    """CPF (Alg. 4.1): propagate through the transition model, weight by the observation
    likelihood, resample (low variance) every update.

    Args:
        world: the transition and observation models (e.g. the planar world).
        resample_size: particles after resampling (default: keep the count).
        outlier_log_evidence: beyond the thesis, a gate on the reading's evidence: a
            reading with log p(o | b+) below it is taken as a sensor fault rather than
            information and the belief is propagated without weighting (reported as
            ``rejected="outlier"``); None (the thesis) weighs every reading. Weighing a
            reading no particle explains puts the whole belief on whichever particles
            explain it least badly (an arm jammed into an obstacle when every sensor
            reads contact), from which it does not come back.
    """

    def __init__(self, world: FilterModel, resample_size: int | None = None, *,
                 outlier_log_evidence: float | None = None):
        _check_gate(outlier_log_evidence)
        self.world = world
        self.resample_size = resample_size
        self.outlier_log_evidence = outlier_log_evidence

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator) -> tuple[ParticleBelief, UpdateDiagnostics]:
        predicted, rejected = _predict(self.world, belief, action, observation, rng)
        if rejected is not None:
            return rejected
        log_w = belief.log_weights + self.world.log_likelihood(observation, predicted, action)
        evidence = _log_evidence(belief, log_w)
        gate = self.outlier_log_evidence
        if gate is not None and evidence < gate:
            return _unweighted(belief, predicted, "outlier", evidence)
        degenerate = _normalised(log_w) is None
        if degenerate:
            log_w = np.array(belief.log_weights)
        posterior = ParticleBelief(predicted, log_w, belief.angular)
        n = self.resample_size or len(belief)
        return (posterior.resample(n, rng=rng),
                UpdateDiagnostics(bool(np.any(observation)), degenerate=degenerate,
                                  log_evidence=evidence))


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
        dual_share: ``fixed`` (the thesis) or ``density``. Alg. 4.2 gives the dual set the
            mass phi at every contact step however improbable its samples are under the
            prior; where the manifold is large (a 7-D arm's, a 3-DOF arm's with one lit
            sensor) a projection may land every dual far from the prior mass, and those
            duals, consistent with every later free-space reading, persist as a spurious
            mode. ``density`` (not in the thesis) compares the prior density the two sets
            see on the manifold: D_d = sum_j w_j b+(d_j) p(o | d_j) over the duals and D_c,
            the mean of b+(s) p(o | s) (b+ leave-one-out) at the conventional set's
            posterior particles, both estimates of the posterior's mean density when each
            set samples the manifold well; the duals get phi * min(1, D_d / D_c). Where no
            conventional particle explains the observation, p(o | s) makes D_c small and
            the duals keep phi (the CPF's failure the duals are there for).
            ``evidence`` (not in the thesis; the idea of Augmented MCL, Thrun, Burgard and
            Fox, Probabilistic Robotics, Table 8.3, which injects samples in proportion to
            how poorly the particles explain the measurements, without its running
            averages): the duals get phi * max(0, 1 - p(o | b+) / max_j p(o | d_j)), the
            reading's evidence under the prior against the likelihood of the duals that
            explain it best (a state on the manifold): 0 when the prior explains the
            reading as well as the manifold does, phi when it cannot explain it at all.
        outlier_log_evidence: the gate of :class:`ConventionalParticleFilter`, on the
            conventional set's evidence, applied only when no dual explains the reading
            either (the draw failed, or the reading is free): a reading the prior does
            not explain but the contact manifold does is what the duals are for.
        dual_lift: None (the thesis: the manifold's samples are the duals), or a map
            ``(duals (M, d), observation, log_density) -> (states (M, d), log b+ (M,))``
            from the manifold's samples to the states the duals stand for, given the
            density they are weighed by (e.g. :class:`estimation.configuration.lift.
            NormalLift`, where the state is a commanded-side configuration behind the
            contact surface).
    """

    def __init__(self, world: FilterModel, manifold: ContactManifold, *,
                 dual_particles: int = 25, mixing_rate: float = 0.1,
                 dual_share: str = "fixed", outlier_log_evidence: float | None = None,
                 dual_lift: DualLift | None = None):
        _check_gate(outlier_log_evidence)
        self.outlier_log_evidence = outlier_log_evidence
        if not 0.0 <= mixing_rate <= 1.0:
            raise ValueError(f"mixing_rate must be in [0, 1], got {mixing_rate}")
        if dual_share not in DUAL_SHARES:
            raise ValueError(f"dual_share must be one of {', '.join(DUAL_SHARES)}, got "
                             f"{dual_share!r}")
        if dual_particles < 1:
            raise ValueError(f"dual_particles must be >= 1, got {dual_particles}")
        self.world = world
        self.manifold = manifold
        self.dual_particles = dual_particles
        self.mixing_rate = mixing_rate
        self.dual_share = dual_share
        self.dual_lift = dual_lift

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator,
               dual_log_density: Callable[[np.ndarray], np.ndarray] | None = None
               ) -> tuple[ParticleBelief, UpdateDiagnostics]:
        """One step of Alg. 4.2; ``dual_log_density`` maps duals (M, d) to log b+ (M,)
        up to a constant (None: the kernel density of the predicted particles, sec. 4.2.3;
        e.g. :class:`estimation.configuration.history.ReadingHistory`'s exact one)."""
        phi = self.mixing_rate
        predicted, rejected = _predict(self.world, belief, action, observation, rng)
        if rejected is not None:
            return rejected
        observation = np.asarray(observation, dtype=bool)
        prior_w = belief.weights
        cpf_ll = self.world.log_likelihood(observation, predicted, action)
        evidence = _log_evidence(belief, belief.log_weights + cpf_ll)
        cpf = _normalised(belief.log_weights + cpf_ll)
        contact = bool(observation.any())
        parts_states, parts_log_w = [], []
        failed = dual_used = False
        if contact:
            duals = self.manifold.sample(
                observation, self.dual_particles, rng=rng,
                predicted=ParticleBelief(predicted, belief.log_weights, belief.angular))
            if dual_log_density is None:
                dual_log_density = partial(log_density, states=predicted, weights=prior_w,
                                           angular=belief.angular)
            if self.dual_lift is not None:
                duals, dual_prior = self.dual_lift(duals, observation, dual_log_density)
            dual_ll = self.world.log_likelihood(observation, duals, action)
            failed = bool(np.all(dual_ll < np.log(SAMPLING_FAILURE_LIKELIHOOD)))
        gate = self.outlier_log_evidence
        if gate is not None and evidence < gate and (failed or not contact):
            return _unweighted(belief, predicted, "outlier", evidence)
        if contact:
            if not failed:
                if self.dual_lift is None:
                    dual_prior = dual_log_density(duals)
                dual = _normalised(dual_prior)
                if dual is not None:
                    dual_used = True
                    if self.dual_share == "density" and cpf is not None:
                        phi *= dual_density_ratio(
                            predicted, prior_w, belief.angular, cpf, cpf_ll, dual,
                            dual_prior + dual_ll, rng=rng)
                    elif self.dual_share == "evidence":
                        phi *= unexplained_share(evidence, dual_ll)
                    parts_states.append(duals)
                    parts_log_w.append(dual + np.log(phi) if phi > 0 else dual - np.inf)
        elif cpf is not None and phi > 0:
            free = ~self.world.in_contact(predicted)
            restricted = _normalised(np.where(free, cpf, -np.inf))
            if restricted is not None:
                # both sets hold the same particles, so each gets its mixed weight once;
                # listed twice, the resampler would drop a tenth of them and copy another
                # tenth at every free step even when all are free, and the belief would
                # drift like a random walk between contacts
                cpf = mixed_log_weights(cpf, restricted, phi)
        degenerate = cpf is None
        if cpf is not None:
            share = 1.0 - phi if parts_states else 1.0
            parts_states.insert(0, predicted)
            parts_log_w.insert(0, cpf + np.log(share) if share > 0 else cpf - np.inf)
        elif not parts_states:  # nothing explains the observation: keep the prediction
            parts_states, parts_log_w = [predicted], [np.log(prior_w)]
        posterior = ParticleBelief(np.concatenate(parts_states), np.concatenate(parts_log_w),
                                   belief.angular)
        diagnostics = UpdateDiagnostics(contact, dual_used, failed, degenerate, evidence)
        return posterior.resample(len(belief), rng=rng), diagnostics


def mixed_log_weights(first: np.ndarray, second: np.ndarray, phi: float) -> np.ndarray:
    """log((1 - phi) exp(first) + phi exp(second)): two normalised log-weight vectors (N,)
    over the same particles, mixed."""
    with np.errstate(divide="ignore"):
        return np.logaddexp(first + np.log1p(-phi), second + np.log(phi))


def unexplained_share(log_evidence: float, dual_log_likelihood: np.ndarray) -> float:
    """max(0, 1 - p(o | b+) / max_j p(o | d_j)), the ``evidence`` share's scale
    (:class:`ManifoldParticleFilter`): ``log_evidence`` the reading's under the prior,
    ``dual_log_likelihood`` (M,) log p(o | d_j) of the duals."""
    best = float(np.max(dual_log_likelihood))
    if not np.isfinite(log_evidence):
        return 1.0
    return float(max(0.0, -np.expm1(min(0.0, log_evidence - best))))


def dual_density_ratio(predicted: np.ndarray, prior_w: np.ndarray, angular: tuple[int, ...],
                       cpf_log_w: np.ndarray, cpf_log_likelihood: np.ndarray,
                       dual_log_w: np.ndarray, dual_log_posterior: np.ndarray, *,
                       rng: np.random.Generator) -> float:
    """min(1, D_d / D_c), the ``density`` share's scale (:class:`ManifoldParticleFilter`).

    D_c: the mean of b+(s) p(o | s) (b+ leave-one-out) over up to :data:`DENSITY_PROBES`
    draws of the conventional set's posterior; D_d: the duals' weighted mean of the same.

    Args:
        predicted: (N, d) the propagated particles (the prior b+); prior_w: (N,) weights.
        angular: the wrapped columns.
        cpf_log_w: (N,) the conventional set's normalised posterior log weights.
        cpf_log_likelihood: (N,) log p(o | s) of the propagated particles.
        dual_log_w: (M,) the duals' normalised log weights.
        dual_log_posterior: (M,) log b+(d) + log p(o | d) at the duals.

    Returns:
        1 when no conventional particle has a neighbour to give it a density.
    """
    p = np.exp(cpf_log_w)
    probes = rng.choice(len(predicted), size=min(DENSITY_PROBES, len(predicted)),
                        p=p / p.sum())
    at_probes = (leave_one_out_log_density(probes, predicted, prior_w, angular=angular)
                 + cpf_log_likelihood[probes])
    log_dc = log_sum_exp(at_probes) - np.log(len(probes))
    if not np.isfinite(log_dc):
        return 1.0
    log_dd = log_sum_exp(dual_log_w + dual_log_posterior)
    return float(np.exp(min(0.0, log_dd - log_dc)))
