"""Online planning with DESPOT: the planner of the ``Planner`` seam, the particle belief
it plans from, and the closed loop that runs episodes on a generative POMDP.

The belief between decisions is a set of N weighted particles (states), as the reference
DESPOT's ``ParticleBelief`` keeps it. After action ``a`` and observation ``o``
(:func:`update_particles`): every particle is stepped with fresh uniforms and its weight
multiplied by ``p(o | s', a)``; the set is resampled (systematic resampling, equal weights
after) only when the effective sample size falls below half of N (the reference's rule).
Resampling at every step instead would, on a model with deterministic transitions
(RockSample's rocks never change), discard rock configurations for good on each noisy
reading (sample impoverishment), which nothing afterwards can undo. When every particle dies
(no particle explains ``o``) the update *ignores the observation*: the stepped particles
keep their prior weights, and the recovery is counted (in :attr:`Episode.recoveries`).
That keeps the planner going on a model whose belief has drifted; a count above zero says
the belief is no longer the posterior.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from planning.pomdp.despot import Despot, DespotSettings, DespotStats, DespotTree
from planning.pomdp.generative import GenerativePOMDP
from planning.protocols import PlanResult


def systematic_resample(weights: np.ndarray, count: int, rng: np.random.Generator
                        ) -> np.ndarray:
    """(count,) indices drawn by systematic resampling from ``weights`` (N,), not all zero."""
    cumulative = np.cumsum(weights / weights.sum())
    positions = (rng.random() + np.arange(count)) / count
    return np.minimum(np.searchsorted(cumulative, positions, side="right"), len(weights) - 1)


RESAMPLE_BELOW = 0.5
"""Resample the belief when its effective sample size falls below this fraction of N."""


def update_particles(model: GenerativePOMDP, particles: np.ndarray, action: int,
                     observation: int, *, rng: np.random.Generator,
                     weights: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray, bool]:
    """The particle belief after ``action`` and ``observation`` (see the module docstring).

    Args:
        particles: (N, d) states; weights: (N,) their weights (None: equal).

    Returns:
        (particles (N, d), normalised weights (N,), whether the update had to recover by
        ignoring the observation).
    """
    n = len(particles)
    prior = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, dtype=float)
    prior = prior / prior.sum()
    u = rng.random((n, model.uniforms_per_step))
    stepped = model.step(particles, action, u).next_states
    log_w = model.log_likelihood(observation, stepped, action)
    live = np.isfinite(log_w) & (prior > 0)
    if not live.any():
        return stepped, prior, True
    w = np.zeros(n)
    w[live] = prior[live] * np.exp(log_w[live] - log_w[live].max())
    w /= w.sum()
    if 1.0 / np.sum(w * w) >= RESAMPLE_BELOW * n:
        return stepped, w, False
    return stepped[systematic_resample(w, n, rng)], np.full(n, 1.0 / n), False


@dataclass(frozen=True)
class DespotMemory:
    """What :class:`DespotPlanner` remembers between decisions: the last tree (for
    subtree reuse, else None) and the action it chose."""

    tree: DespotTree | None = None
    action: int | None = None


class DespotPlanner:
    """DESPOT behind the ``Planner`` protocol: ``plan(particles (N, d), *, rng, memory,
    observation) -> PlanResult`` with the action, every action ranked by its root bounds
    and the search's statistics (:class:`~planning.pomdp.despot.DespotStats` as a dict).

    Args:
        model: the generative POMDP.
        settings: the search's settings.
        upper_bound, default_actions: optional replacements of the model's bounds.
    """

    phase = "despot"

    def __init__(self, model: GenerativePOMDP, settings: DespotSettings | None = None, *,
                 upper_bound=None, default_actions=None):
        settings = settings or DespotSettings()
        self.model = model
        self.settings = settings
        self.search = Despot(model, settings, upper_bound=upper_bound,
                             default_actions=default_actions)

    def plan(self, belief: np.ndarray, *, rng: np.random.Generator,
             memory: DespotMemory | None = None, observation: int | None = None,
             weights: np.ndarray | None = None, **context) -> PlanResult:
        """The decision for the particle belief ``belief`` (N, d) with ``weights`` (N,)
        (None: equal). With subtree reuse, ``observation`` (received after the last
        decision's action) selects the subtree."""
        start = time.perf_counter()
        memory = memory or DespotMemory()
        previous = None
        if (self.settings.reuse == "subtree" and memory.tree is not None
                and observation is not None):
            previous = self.search.subtree(memory.tree, memory.action, observation, rng=rng)
        action, stats, tree = self.search.search(belief, rng=rng, weights=weights,
                                                 previous=previous)
        ranking = self.search.ranking(tree.root)
        if ranking is None or ranking[0] != action:
            ranking = (action, *[a for a in range(len(self.model.actions)) if a != action])
        kept = tree if self.settings.reuse == "subtree" else None
        return PlanResult(action=action, ranking=ranking, phase=self.phase,
                          planning_ms=(time.perf_counter() - start) * 1e3,
                          stats=stats_dict(stats),
                          memory=DespotMemory(kept, action))


def stats_dict(stats: DespotStats) -> dict:
    """The search statistics as a plain dict."""
    return {name: getattr(stats, name) for name in stats.__dataclass_fields__}


@dataclass(frozen=True)
class Episode:
    """One episode of online planning.

    Attributes:
        discounted_return: sum_t gamma^t r_t.
        undiscounted_return: sum_t r_t.
        steps: decisions taken (the episode ends at a terminal state or the step limit).
        decision_ms: (steps,) wall time of each decision (ms).
        overrun_ms: (steps,) time beyond the budget of each decision (ms).
        trials, nodes: (steps,) per decision.
        recoveries: belief updates that had to ignore the observation.
        crossings_repaired: bound crossings repaired over the episode.
    """

    discounted_return: float
    undiscounted_return: float
    steps: int
    decision_ms: np.ndarray
    overrun_ms: np.ndarray
    trials: np.ndarray
    nodes: np.ndarray
    recoveries: int
    crossings_repaired: int


def run_episode(model: GenerativePOMDP, planner: DespotPlanner, *, rng: np.random.Generator,
                steps: int = 90, particles: int = 1000) -> Episode:
    """Plan online from the model's initial belief for up to ``steps`` decisions: the true
    state is drawn from the initial belief and stepped with the model; the planner sees
    only the observations (its belief: :func:`update_particles`)."""
    state = model.sample_initial(1, rng=rng)
    belief = model.sample_initial(particles, rng=rng)
    weights = None
    memory, observation = None, None
    total = undiscounted = 0.0
    scale = 1.0
    records = {k: [] for k in ("decision_ms", "overrun_ms", "trials", "nodes")}
    recoveries = crossings = 0
    taken = 0
    for _ in range(steps):
        if model.is_terminal(state)[0]:
            break
        result = planner.plan(belief, rng=rng, memory=memory, observation=observation,
                              weights=weights)
        memory = result.memory
        stats = result.stats
        records["decision_ms"].append(result.planning_ms)
        records["overrun_ms"].append(stats["overrun_ms"])
        records["trials"].append(stats["trials"])
        records["nodes"].append(stats["nodes"])
        crossings += stats["crossings_repaired"]
        step = model.step(state, result.action, rng.random((1, model.uniforms_per_step)))
        total += scale * float(step.rewards[0])
        undiscounted += float(step.rewards[0])
        scale *= model.discount
        state, observation = step.next_states, int(step.observations[0])
        belief, weights, recovered = update_particles(model, belief, result.action,
                                                      observation, rng=rng, weights=weights)
        recoveries += recovered
        taken += 1
    return Episode(total, undiscounted, taken,
                   *(np.asarray(records[k], dtype=float) for k in
                     ("decision_ms", "overrun_ms", "trials", "nodes")),
                   recoveries, crossings)
