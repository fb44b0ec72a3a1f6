"""Rel-DESPOT planning on the continuous planar model (``rel-despot-continuous``), beyond
the thesis: its episodes for ``cmanip experiment latdespot --part rel``.

The thesis' policies plan on the discrete Rel-POMDP and track the discrete belief (sec.
6.4.1); this one plans with DESPOT on the continuous model itself
(:class:`~planning.hand.generative.ContinuousHandGenerative`, Rel-QMDP as its upper bound
and rollout policy, as the thesis' Rel-DESPOT) and tracks the object with the project's
manifold particle filter (thesis Alg. 4.2, analytic manifold: the sensors discriminate
contact perfectly, so a conventional filter's particles would rarely land on the contact
manifold). Episode j is seeded from (seed, 19, j) and depends on nothing else, so episodes
run on the trial runner, any backend (each process builds the model once from the
settings).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from estimation.hand.manifolds import AnalyticManifold
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from experiments.runner import Backend, Job, map_trials
from experiments.statistics import half_width, wilson_interval
from planning.hand.generative import ContinuousHandGenerative
from planning.pomdp.despot import DespotSettings
from planning.pomdp.online import DespotPlanner

EPISODE_STREAM = 19


@dataclass(frozen=True)
class ContinuousEpisode:
    """One episode of Rel-DESPOT on the continuous model.

    Attributes:
        in_goal: (horizon + 1,) bool, the object's centre in the goal before each step
            and after the last.
        discounted_return: sum_t gamma^t R(s_t) on the continuous model.
        planning_ms: (horizon,) wall time of each decision (ms).
        trials: (horizon,) DESPOT trials of each decision.
        crossings_repaired: bound crossings the searches repaired.
        degenerate_updates: filter updates where no particle explained the reading.
    """

    in_goal: np.ndarray
    discounted_return: float
    planning_ms: np.ndarray
    trials: np.ndarray
    crossings_repaired: int
    degenerate_updates: int


class EpisodeRunner:
    """What one process needs to run episodes, built once from the settings with
    ``build(settings) -> (HandPOMDP, GaussianBelief, ...)``."""

    def __init__(self, settings, build):
        self.settings = settings
        model, self.belief, _ = build(settings)
        self.model = model
        self.generative = ContinuousHandGenerative(model, self.belief,
                                                   rollout=settings.continuous_rollout)
        self.planner = DespotPlanner(self.generative, DespotSettings(
            scenarios=settings.despot_scenarios, depth=settings.despot_depth,
            max_trials=settings.continuous_despot_trials, seconds=settings.despot_seconds))
        world = model.world
        self.filter = make_filter("mpf", world, AnalyticManifold(world))

    def run(self, episode: int, *, on_decision=None) -> ContinuousEpisode:
        """Episode ``episode``; ``on_decision()`` is called after each decision's update
        (the memory bench samples there)."""
        s, model, world = self.settings, self.model, self.model.world
        rng = np.random.default_rng([s.seed, EPISODE_STREAM, episode])
        state = self.belief.sample(world, 1, rng=rng)
        belief = ParticleBelief.uniform(self.belief.sample(world, s.despot_particles, rng=rng))
        vectors = self.generative.vectors
        in_goal = np.zeros(s.horizon + 1, dtype=bool)
        in_goal[0] = model.in_goal(state)[0]
        planning_ms, trials = np.zeros(s.horizon), np.zeros(s.horizon)
        total, crossings, degenerate = 0.0, 0, 0
        for t in range(s.horizon):
            result = self.planner.plan(belief.resample(rng=rng).states, rng=rng)
            planning_ms[t], trials[t] = result.planning_ms, result.stats["trials"]
            crossings += result.stats["crossings_repaired"]
            total -= model.spec.discount ** t * (not in_goal[t])
            action = vectors[result.action]
            state = world.sample_step(state, action, rng=rng)
            reading = world.sample_observation(state, rng.random((1, 2)))[0]
            belief, diagnostics = self.filter.update(belief, action, reading, rng=rng)
            degenerate += diagnostics.degenerate
            in_goal[t + 1] = model.in_goal(state)[0]
            if on_decision is not None:
                on_decision()
        return ContinuousEpisode(in_goal, total, planning_ms, trials, crossings, degenerate)


@lru_cache(maxsize=2)
def _runner(settings, build) -> EpisodeRunner:
    return EpisodeRunner(settings, build)


def continuous_episode(settings, build, episode: int) -> ContinuousEpisode:
    """Episode ``episode`` in whichever process the trial runner chose (the problem built
    once per process)."""
    return _runner(settings, build).run(episode)


def run_continuous_episodes(settings, build, *, backend: Backend = Backend(),
                            progress: bool = True) -> list[ContinuousEpisode]:
    """``settings.trials`` episodes (in episode order) on the trial runner's ``backend``,
    each process building the problem with ``build(settings)`` (a module-level function,
    so that it reaches other processes by name; e.g.
    :func:`experiments.latdespot_study.build_rel_problem`)."""
    jobs = [Job(f"rel-despot-continuous/{j}", (settings, build, j))
            for j in range(settings.trials)]
    return map_trials(continuous_episode, jobs, backend=backend,
                      desc="rel rel-despot-continuous", progress=progress)


def summarise_episodes(episodes: list[ContinuousEpisode]) -> dict:
    """The summary entry of ``rel-despot-continuous`` from its episodes
    (its value is the continuous model's), in the study's summary format."""
    success = np.stack([e.in_goal for e in episodes], axis=1)
    returns = np.array([e.discounted_return for e in episodes])
    lo, hi = wilson_interval(int(success[-1].sum()), len(episodes))
    value, half = float(returns.mean()), float(half_width(returns))
    planning = np.concatenate([e.planning_ms for e in episodes])
    return {"discounted_value": value, "discounted_value_ci95": half,
            "value_model": "continuous", "trials": len(episodes),
            "success_rate": float(success[-1].mean()), "success_rate_ci95": [lo, hi],
            "success_over_time": success.mean(axis=1).tolist(),
            "continuous_discounted_value": value, "continuous_discounted_value_ci95": half,
            "planning_ms_median": float(np.median(planning)),
            "planning_ms_p99": float(np.percentile(planning, 99)),
            "decisions": len(planning),
            "despot_trials_median": float(np.median(np.concatenate(
                [e.trials for e in episodes]))),
            "crossings_repaired": int(sum(e.crossings_repaired for e in episodes)),
            "degenerate_updates": int(sum(e.degenerate_updates for e in episodes))}
