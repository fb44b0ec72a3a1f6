"""The one place particle filters are built, from a kind name, for the studies, the closed
loop and the command line alike."""

from __future__ import annotations

from estimation.particles.filters import (
    ContactManifold,
    ConventionalParticleFilter,
    DualLift,
    ManifoldParticleFilter,
)
from models.protocols import FilterModel

FILTER_KINDS = ("cpf", "mpf")
"""``cpf``: the conventional particle filter (thesis Alg. 4.1); ``mpf``: the manifold
particle filter (Alg. 4.2), which needs a contact-manifold representation."""


def make_filter(kind: str, world: FilterModel, manifold: ContactManifold | None = None, *,
                dual_particles: int = 25, mixing_rate: float = 0.1,
                dual_share: str = "fixed", resample_size: int | None = None,
                outlier_log_evidence: float | None = None, dual_lift: DualLift | None = None
                ) -> ConventionalParticleFilter | ManifoldParticleFilter:
    """A filter of ``kind`` over ``world``'s transition and observation models.

    Args:
        kind: one of :data:`FILTER_KINDS`.
        world: the batched models (e.g. :class:`models.planar.world.PlanarWorld`).
        manifold: the MPF's dual proposal (analytic, rejection-sampled, rollout, implicit);
            required for ``mpf``, ignored for ``cpf``.
        dual_particles: the MPF's nd (thesis sec. 4.3.2: 25).
        mixing_rate: the MPF's phi in [0, 1] (sec. 4.3.2: 0.1).
        dual_share: the MPF's split between its sets, ``fixed`` (Alg. 4.2), ``density`` or
            ``evidence`` (:class:`ManifoldParticleFilter`).
        resample_size: the CPF's particle count after resampling (default: unchanged).
        outlier_log_evidence: either filter's outlier gate (None: the thesis; see
            :class:`ConventionalParticleFilter`).
        dual_lift: the MPF's map from manifold samples to states (None: the thesis;
            :class:`ManifoldParticleFilter`).

    Raises:
        ValueError: an unknown kind, or ``mpf`` without a manifold.
    """
    if kind == "cpf":
        return ConventionalParticleFilter(world, resample_size,
                                          outlier_log_evidence=outlier_log_evidence)
    if kind == "mpf":
        if manifold is None:
            raise ValueError("the MPF needs a contact-manifold representation")
        return ManifoldParticleFilter(world, manifold, dual_particles=dual_particles,
                                      mixing_rate=mixing_rate, dual_share=dual_share,
                                      outlier_log_evidence=outlier_log_evidence,
                                      dual_lift=dual_lift)
    raise ValueError(f"unknown filter kind {kind!r}; choose from {', '.join(FILTER_KINDS)}")
