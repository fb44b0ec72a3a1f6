"""``cmanip experiment closedloop``: the thesis' real-robot experiment (sec. 6.5) in the
Drake world.

Episodes start from the three initial beliefs of sec. 6.5 (means 35 cm ahead at lateral
offsets -12, 0 and +6 cm, standard deviation 5 cm; 15 deg in orientation as sec. 6.4.2).
Trial ``j`` uses belief ``j mod 3`` and the episode seed ``(seed, j)``, which fixes the
true object pose and the initial particles, so both policies meet the same thirty objects,
as on the robot ("we drew ten samples from each initial belief state and used the
resulting thirty samples [...] to evaluate both policies"). Episodes run through the trial
runner (:mod:`experiments.runner`): any backend, each kept in ``trials.jsonl`` as it
finishes, a killed study resumable. Writes ``summary.json`` (per
policy ``success_rate`` with its 95 % Wilson interval, ``infeasible_actions`` executed,
``planning_ms_median``, and every trial's summary) and ``closedloop.png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from diagrams.herb.closed_loop import estimator_filter
from diagrams.herb.episode import run_episode
from diagrams.herb.settings import (
    EPISODE_CEILINGS,
    POLICIES,
    THESIS_BELIEF_MEANS,
    EpisodeSettings,
)
from experiments.runner import Backend, Job, TrialStore, map_trials
from experiments.statistics import wilson_interval
from models.settings import check_ranges, settings_to_dict
from planning.hand.solution import HandSolution, HandSolveSettings, solve_hand_problem

THESIS_REAL_ROBOT = {"pomdp": {"successes": 27, "trials": 30},
                     "qmdp": {"successes": 20, "trials": 30}}


@dataclass(frozen=True)
class ClosedLoopSettings:
    """Attributes:
        policies: which post-contact policies to run.
        trials: episodes per policy.
        seed: master seed (episode ``j`` is seeded from ``(seed, j)``).
        beliefs: the initial belief means (hand frame: x m, y m, theta rad); episode ``j``
            starts from belief ``j mod len(beliefs)``.
        episode: every other setting of an episode (its policy, belief mean and seed are
            the study's).
    """

    policies: tuple[str, ...] = ("qmdp", "pomdp")
    trials: int = 30
    seed: int = 0
    beliefs: tuple[tuple[float, float, float], ...] = THESIS_BELIEF_MEANS
    episode: EpisodeSettings = EpisodeSettings()

    def __post_init__(self):
        if self.trials < 1:
            raise ValueError(f"trials must be >= 1, got {self.trials}")
        unknown = set(self.policies) - set(POLICIES)
        if unknown:
            raise ValueError(f"policies must be drawn from {POLICIES}, got {self.policies}")
        check_ranges(self, at_most={"beliefs": EPISODE_CEILINGS["belief_mean"]})

    @property
    def runs(self) -> tuple[str, ...]:
        """The summary's keys: the policies of the ``hand`` planner, or the planner."""
        return self.policies if self.episode.planner == "hand" else (self.episode.planner,)

    def episode_settings(self, run: str, trial: int) -> EpisodeSettings:
        """The settings of episode ``trial`` of ``run`` (a policy, or the planner)."""
        policy = run if self.episode.planner == "hand" else self.episode.policy
        return replace(self.episode, policy=policy,
                       belief_mean=self.beliefs[trial % len(self.beliefs)],
                       seed=int(np.random.SeedSequence([self.seed, trial]).generate_state(1)[0]))


@lru_cache(maxsize=2)
def _solution(solver: HandSolveSettings, cache_dir: str | None) -> HandSolution:
    """The solved planning model, once per process: loaded from ``cache_dir`` (where the
    command solved it before the study began), solved when it is not there."""
    return solve_hand_problem(solver, cache_dir=None if cache_dir is None else Path(cache_dir),
                              progress=False)


@lru_cache(maxsize=2)
def _shared_filter(kind: str, gate: float | None, solver: HandSolveSettings,
                   cache_dir: str | None):
    """One estimator filter per process (``gate``: its outlier gate), shared by its
    episodes (its manifold is costly)."""
    return estimator_filter(kind, _solution(solver, cache_dir).model.world, gate)


def closedloop_trial(settings: ClosedLoopSettings, solver: HandSolveSettings,
                     cache_dir: str | None, run: str, trial: int) -> dict:
    """Episode ``trial`` of ``run`` (a policy or the planner): its summary, with the trial
    and the initial belief (1-based)."""
    solution = _solution(solver, cache_dir)
    episode = run_episode(settings.episode_settings(run, trial), solution, progress=False,
                          filter=_shared_filter(settings.episode.estimator,
                                                settings.episode.estimator_outlier_log_evidence,
                                                solver, cache_dir),
                          cache_dir=None if cache_dir is None else Path(cache_dir))
    summary = dict(episode.summary)
    summary["trial"] = trial
    summary["belief"] = trial % len(settings.beliefs) + 1
    return summary


def trial_store(settings: ClosedLoopSettings, solver: HandSolveSettings, out: Path, *,
                resume: bool) -> TrialStore:
    """``out/trials.jsonl``, keyed by every setting an episode depends on (not the policies
    or the trial count, which only choose episodes: a resumed study may add some)."""
    relevant = {k: v for k, v in settings_to_dict(settings).items()
                if k not in ("policies", "trials")}
    return TrialStore(out, "closedloop", {"study": relevant,
                                          "solver": settings_to_dict(solver)}, resume=resume)


def run_closedloop_study(settings: ClosedLoopSettings, solver: HandSolveSettings, out: Path, *,
                         backend: Backend = Backend(), resume: bool = False,
                         progress: bool = True, cache_dir: Path | None = None) -> dict:
    """Run every (policy or planner, trial) episode on ``backend`` (each kept in
    ``out/trials.jsonl`` as it finishes; ``resume`` runs only the missing ones); write and
    return the summary. ``cache_dir`` holds the solved model (and the lattice's IK table,
    for ``lat-despot``); each worker loads them from there."""
    out.mkdir(parents=True, exist_ok=True)
    cache = None if cache_dir is None else str(cache_dir)
    store = trial_store(settings, solver, out, resume=resume)
    jobs = [Job(f"{run}/{j}", (settings, solver, cache, run, j))
            for run in settings.runs for j in range(settings.trials)]
    results = map_trials(closedloop_trial, jobs, backend=backend, store=store,
                         desc="closed loop", progress=progress)
    runs = {run: _aggregate([r for job, r in zip(jobs, results, strict=True)
                             if job.args[3] == run]) for run in settings.runs}
    summary = {"policies": runs, "thesis_real_robot": THESIS_REAL_ROBOT,
               "settings": settings_to_dict(settings),
               "model_timings_s": _solution(solver, cache).timings}
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    from experiments.closedloop_plots import plot_closedloop

    plot_closedloop(summary, out / "closedloop.png")
    return summary


def _aggregate(trials: list[dict]) -> dict:
    successes = sum(t["success"] for t in trials)
    lo, hi = wilson_interval(successes, len(trials))
    planning = [ms for t in trials for ms in t["planning_ms"]]
    beliefs = sorted({t["belief"] for t in trials})
    return {
        "success_rate": successes / len(trials),
        "success_rate_ci95": [lo, hi],
        "successes": successes,
        "trials": len(trials),
        "success_by_belief": {str(b): [t["success"] for t in trials if t["belief"] == b]
                              for b in beliefs},
        "infeasible_actions": sum(t["infeasible_actions"] for t in trials),
        "infeasible_rejected": sum(t["infeasible_rejected"] for t in trials),
        "planning_ms_median": float(np.median(planning)) if planning else None,
        "stop_reasons": {r: sum(t["stop_reason"] == r for t in trials)
                         for r in sorted({t["stop_reason"] for t in trials})},
        "final_distance_to_goal_m": [t["final_distance_to_goal_m"] for t in trials],
        "estimator_rmse_m_mean": float(np.mean([t["estimator_rmse_m"]["mean"]
                                                for t in trials])),
        "lattice_edge_fraction_median": (float(np.median(
            [t["lattice"]["edge_fraction_evaluated"] for t in trials]))
            if all("lattice" in t for t in trials) else None),
        "episodes": trials,
    }
