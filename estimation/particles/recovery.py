"""Falling back on the prior when the readings stop making sense (beyond the thesis).

A particle filter whose particles have all left the region the readings point to cannot
come back by itself: resampling only copies what is there. After a stuck sensor, a burst
of contradicting readings or a dual draw on a reading no state explains, the conventional
and the manifold particle filter can sit on a wrong belief for the rest of a run.
:class:`PriorFallback` wraps either filter and, once the readings have surprised the
belief for ``patience`` updates in a row (their evidence ``p(o | b+)`` below
``surprise``), replaces a ``fraction`` of the particles by draws from the *prior
predictive*: a cloud drawn from the initial belief and moved by every action since, never
weighted by a reading, sampled here in proportion to how well each of its members explains
the current reading. This is sensor-resetting localisation (Lenser and Veloso, ICRA 2000)
with the prior predictive as the reset distribution, and the trigger of augmented MCL
(Thrun, Burgard and Fox, Probabilistic Robotics, 2005, sec. 8.3.5) made a count of
surprising updates rather than a ratio of evidence averages: the evidence of a contact
reading is orders of magnitude below a free one's, so a ratio of averages would fire at
every contact onset.

The wrapper carries the cloud and the count from update to update: one per run.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import UpdateDiagnostics, non_finite_input
from models.protocols import FilterModel

SURPRISE = 1e-3
"""A reading whose evidence p(o | b+) is below this surprises the belief."""


class PriorFallback:
    """A filter (CPF or MPF) that falls back on the prior predictive (module docstring).

    Args:
        filter: the wrapped filter (``update(belief, action, observation, *, rng)``).
        world: its transition and observation models.
        prior: (M, d) states drawn from the initial belief.
        surprise: evidence threshold of a surprising reading.
        patience: surprising updates in a row before the fallback acts.
        fraction: share of the particles replaced at each update while it acts.

    Attributes:
        injections: updates at which prior particles were injected.
    """

    def __init__(self, filter, world: FilterModel, prior: np.ndarray, *,
                 surprise: float = SURPRISE, patience: int = 3, fraction: float = 0.2):
        if not 0 < surprise < 1 or patience < 1 or not 0 < fraction <= 1:
            raise ValueError("surprise must be in (0, 1), patience >= 1, fraction in (0, 1]")
        self.filter, self.world = filter, world
        self.prior = np.array(prior, dtype=float)
        self.surprise, self.patience, self.fraction = surprise, patience, fraction
        self.surprised = 0
        self.injections = 0

    def update(self, belief: ParticleBelief, action: np.ndarray, observation: np.ndarray, *,
               rng: np.random.Generator) -> tuple[ParticleBelief, UpdateDiagnostics]:
        if non_finite_input(action, observation) != "action":
            self.prior = self.world.sample_step(self.prior, action, rng=rng)
        belief, diag = self.filter.update(belief, action, observation, rng=rng)
        if diag.rejected:
            return belief, diag
        surprising = diag.log_evidence < np.log(self.surprise)
        self.surprised = self.surprised + 1 if surprising else 0
        if self.surprised < self.patience:
            return belief, diag
        k = int(np.ceil(self.fraction * len(belief)))
        log_l = self.world.log_likelihood(observation, self.prior, action)
        p = np.exp(log_l - log_l.max()) if np.isfinite(log_l.max()) else np.ones(len(log_l))
        draws = self.prior[rng.choice(len(self.prior), k, p=p / p.sum())]
        replaced = rng.choice(len(belief), k, replace=False)
        states = np.array(belief.states)
        states[replaced] = draws
        log_w = np.array(belief.log_weights)
        log_w[replaced] = np.log(np.mean(np.exp(log_w - log_w.max()))) + log_w.max()
        self.injections += 1
        return (ParticleBelief(states, log_w, belief.angular),
                replace(diag, reinvigorated=k))
