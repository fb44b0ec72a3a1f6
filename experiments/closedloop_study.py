"""``cmanip experiment closedloop``: the thesis' real-robot experiment (sec. 6.5) in the
Drake world.

Episodes start from the three initial beliefs of sec. 6.5 (means 35 cm ahead at lateral
offsets -12, 0 and +6 cm, standard deviation 5 cm; 15 deg in orientation as sec. 6.4.2).
Trial ``j`` uses belief ``j mod 3`` and the episode seed ``(seed, j)``, which fixes the
true object pose and the initial particles, so both policies meet the same thirty objects,
as on the robot ("we drew ten samples from each initial belief state and used the
resulting thirty samples [...] to evaluate both policies"). Writes ``summary.json`` (per
policy ``success_rate`` with its 95 % Wilson interval, ``infeasible_actions`` executed,
``planning_ms_median``, and every trial's summary) and ``closedloop.png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from diagrams.herb.closed_loop import estimator_filter
from diagrams.herb.episode import run_episode
from diagrams.herb.settings import POLICIES, THESIS_BELIEF_MEANS, EpisodeSettings
from experiments.statistics import wilson_interval
from models.settings import settings_to_dict
from planning.hand.solution import HandSolution

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


def run_closedloop_study(settings: ClosedLoopSettings, solution: HandSolution, out: Path, *,
                         progress: bool = True, cache_dir: Path | None = None) -> dict:
    """Run every (policy or planner, trial) episode; write and return the summary
    (``cache_dir``: where the lattice's IK table is kept, for ``lat-despot``)."""
    out.mkdir(parents=True, exist_ok=True)
    shared = estimator_filter(settings.episode.estimator, solution.model.world)
    results: dict[str, dict] = {}
    for policy in settings.runs:
        trials = []
        for j in tqdm(range(settings.trials), desc=f"closed loop ({policy})", unit="episode",
                      disable=not progress):
            episode = run_episode(settings.episode_settings(policy, j), solution, progress=False,
                                  filter=shared, cache_dir=cache_dir)
            summary = episode.summary
            summary["trial"] = j
            summary["belief"] = j % len(settings.beliefs) + 1
            trials.append(summary)
        results[policy] = _aggregate(trials)
    summary = {"policies": results, "thesis_real_robot": THESIS_REAL_ROBOT,
               "settings": settings_to_dict(settings), "model_timings_s": solution.timings}
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
