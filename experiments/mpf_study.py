"""The MPF study: thesis sec. 4.3 (Figs. 4.6-4.9) and seed 000 sec. 7 (Figs. 5-6).

A trial (sec. 4.3.1): the hand pushes straight ahead for ``push_distance_m`` (50 cm at
1 cm/s); the initial belief is N(mean, diag(5 cm, 5 cm, 20 deg)^2) with the mean 20 cm ahead
of the palm, lateral offset ~ U[-10, 10] cm, orientation ~ U[0, 360) deg; the true pose is a
draw from it; every ``update_interval_m`` of travel the true object is stepped with the
pushing model, the sensors read it, and every filter updates on the same reading. All
filters of a trial share its truth (paired comparisons). RMSE is aligned at the first
update whose true state touches the hand (t = 0); "post-contact" averages the updates after.

Parts: ``compare`` (CPF vs MPF-AM), ``resolution`` (three sensor layouts), ``rate`` (5 mm to
4 cm between updates), ``representations`` (AM, RS, TR + sampling failures), ``mixing``
(phi), ``all``. Each writes ``summary.json`` and PNG figures with 95 % confidence intervals.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from estimation.hand.manifolds import (
    AnalyticManifold,
    RejectionSampledManifold,
    TrajectoryRolloutManifold,
)
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from experiments.mpf_plots import plot_part, plot_world
from experiments.runner import Backend, Job, TrialStore, map_trials
from experiments.statistics import half_width
from models.planar.world import PlanarWorld
from models.settings import check_ranges

PARTS = ("compare", "resolution", "rate", "representations", "mixing")
RESOLUTIONS = ("low", "medium", "high")
UPDATE_INTERVALS_M = (0.005, 0.01, 0.02, 0.04)
MIXING_RATES = (0.025, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0)


@dataclass(frozen=True)
class TrialSettings:
    """Parameters of one trial (thesis sec. 4.3.1 and 4.3.2 defaults).

    Attributes:
        object: object name or YAML path; sensors: planar sensor layout name or path.
        push_distance_m: hand travel per trial; update_interval_m: travel between updates.
        mean_ahead_m: belief mean distance ahead of the palm; lateral_range_m: the mean's
            lateral offset is uniform in +-this.
        std: (3,) belief standard deviations (m, m, rad).
        particles: CPF n and MPF nc; dual_particles: MPF nd; mixing_rate: MPF phi.
        am_dtheta_deg: AM angular resolution (linear resolution 1 mm).
        rs_size, rs_epsilon_m: RS set size and band; tr_rollouts, tr_per_rollout: TR.
    """

    object: str = "box"
    sensors: str = "medium"
    push_distance_m: float = 0.5
    update_interval_m: float = 0.005
    mean_ahead_m: float = 0.20
    lateral_range_m: float = 0.10
    std: tuple[float, float, float] = (0.05, 0.05, float(np.deg2rad(20.0)))
    particles: int = 100
    dual_particles: int = 25
    mixing_rate: float = 0.1
    am_dtheta_deg: float = 1.15
    rs_size: int = 10_000
    rs_epsilon_m: float = 0.001
    tr_rollouts: int = 2000
    tr_per_rollout: int = 5

    def __post_init__(self):
        if not 0.0 < self.push_distance_m <= 2.0:
            raise ValueError(f"push_distance_m {self.push_distance_m} m is outside (0, 2] m")
        if not 0.0 < self.update_interval_m <= self.push_distance_m:
            raise ValueError(f"update_interval_m must be in (0, push_distance_m], got "
                             f"{self.update_interval_m}")
        if min(self.std) <= 0 or self.particles < 1 or self.dual_particles < 1:
            raise ValueError("std must be > 0, particles and dual_particles >= 1")
        if not 0.0 <= self.mixing_rate <= 1.0:
            raise ValueError(f"mixing_rate must be in [0, 1], got {self.mixing_rate}")
        check_ranges(self, positive=("am_dtheta_deg", "rs_epsilon_m"),
                     non_negative=("lateral_range_m",),
                     counts=("rs_size", "tr_rollouts", "tr_per_rollout"),
                     at_most={"mean_ahead_m": 1.0, "lateral_range_m": 1.0, "std": 10.0,
                              "am_dtheta_deg": 360.0, "rs_epsilon_m": 0.1})

    @property
    def updates(self) -> int:
        return int(round(self.push_distance_m / self.update_interval_m))


@dataclass(frozen=True)
class FilterSpec:
    """A filter of a study: ``kind`` in cpf, am, rs, tr; label used in outputs."""

    label: str
    kind: str
    mixing_rate: float | None = None


@dataclass
class TrialResult:
    """Per-update records of one trial: arrays (F, T) for the F filters; ``reading_correct``
    (T,) says whether the sensors reported the true (noise-free) reading."""

    contact_index: int | None
    reading_correct: np.ndarray
    rmse_m: np.ndarray
    rmse_rad: np.ndarray
    contact_observed: np.ndarray
    sampling_failed: np.ndarray
    dual_used: np.ndarray


@dataclass(frozen=True)
class Condition:
    """One set of trials: settings plus the filters run on them."""

    name: str
    settings: TrialSettings
    filters: tuple[FilterSpec, ...]
    extra: dict = field(default_factory=dict)


@lru_cache(maxsize=8)
def _world(object_name: str, sensors: str) -> PlanarWorld:
    return PlanarWorld.load(object_name, sensors)


@lru_cache(maxsize=8)
def _analytic(object_name: str, sensors: str, dtheta_deg: float) -> AnalyticManifold:
    return AnalyticManifold(_world(object_name, sensors), dtheta_rad=np.deg2rad(dtheta_deg))


@lru_cache(maxsize=8)
def _rejection(object_name: str, sensors: str, size: int, epsilon: float,
               seed: int) -> RejectionSampledManifold:
    """The fixed RS set of a study: drawn once from the study seed, reused by every trial."""
    return RejectionSampledManifold(_world(object_name, sensors), size=size,
                                    epsilon_m=epsilon, rng=np.random.default_rng([seed, 7]))


def initial_belief_mean(settings: TrialSettings, rng: np.random.Generator) -> np.ndarray:
    """(3,) the trial's belief mean (sec. 4.3.1)."""
    return np.array([settings.mean_ahead_m,
                     rng.uniform(-settings.lateral_range_m, settings.lateral_range_m),
                     rng.uniform(-np.pi, np.pi)])


@dataclass(frozen=True)
class TrialTruth:
    """One trial's simulated push (sec. 4.3.1).

    Attributes:
        mean, std: (3,) the belief's mean and standard deviations (m, m, rad).
        action: (3,) the hand's motion per update (m, m, rad).
        true_states: (T, 3) the object's pose in the hand frame after each update.
        observations: (T, S) bool, the sensors' readings after each update.
    """

    mean: np.ndarray
    std: np.ndarray
    action: np.ndarray
    true_states: np.ndarray
    observations: np.ndarray


def simulate_truth(settings: TrialSettings, study_seed: int, trial: int) -> TrialTruth:
    """The push of trial ``trial``, seeded from (study_seed, trial, 0)."""
    world = _world(settings.object, settings.sensors)
    truth_rng = np.random.default_rng([study_seed, trial, 0])
    mean = initial_belief_mean(settings, truth_rng)
    std = np.asarray(settings.std)
    action = np.array([settings.update_interval_m, 0.0, 0.0])
    true_states, observations = [], []
    state = world.sample_gaussian(mean, std, 1, rng=truth_rng)
    for _ in range(settings.updates):
        state = world.sample_step(state, action, rng=truth_rng)
        true_states.append(state[0])
        observations.append(world.sample_observation(state, truth_rng.random((1, 2)))[0])
    return TrialTruth(mean, std, action, np.array(true_states), np.array(observations))


def run_trial(settings: TrialSettings, filters: tuple[FilterSpec, ...], study_seed: int,
              trial: int) -> TrialResult:
    """Run every filter on one trial's truth; reproducible from (study_seed, trial)."""
    world = _world(settings.object, settings.sensors)
    truth = simulate_truth(settings, study_seed, trial)
    mean, std, action = truth.mean, truth.std, truth.action
    true_states, observations = truth.true_states, truth.observations
    reading_correct = (world.sensing.true_contacts(true_states) == np.array(observations)).all(1)
    touching = world.in_contact(true_states)
    contact_index = int(np.argmax(touching)) if touching.any() else None

    F, T = len(filters), settings.updates
    rmse_m, rmse_rad = np.zeros((F, T)), np.zeros((F, T))
    observed, failed, dual = (np.zeros((F, T), dtype=bool) for _ in range(3))
    for f, spec in enumerate(filters):
        rng = np.random.default_rng([study_seed, trial, 1, f])
        estimator = build_filter(world, settings, spec, mean, std, action, study_seed, rng)
        belief = ParticleBelief.uniform(
            world.sample_gaussian(mean, std, settings.particles, rng=rng))
        for t in range(T):
            belief, diag = estimator.update(belief, action, observations[t], rng=rng)
            rmse_m[f, t], rmse_rad[f, t] = belief.rmse(true_states[t])
            observed[f, t], failed[f, t] = diag.contact_observed, diag.sampling_failed
            dual[f, t] = diag.dual_used
    return TrialResult(contact_index, reading_correct, rmse_m, rmse_rad, observed, failed, dual)


def build_filter(world, settings: TrialSettings, spec: FilterSpec, mean, std, action,
                 study_seed: int, rng: np.random.Generator, *,
                 outlier_log_evidence: float | None = None, dual_share: str = "fixed"):
    """The filter of ``spec`` for a trial: the CPF, or the MPF with the AM, RS (the
    study's shared set) or TR (this trial's rollouts from the belief) manifold; with
    ``outlier_log_evidence``, its outlier gate, and ``dual_share``, the MPF's split between
    its sets (:class:`estimation.particles.filters.ManifoldParticleFilter`; the study's
    filters are the thesis', with no gate and the fixed split)."""
    if spec.kind == "cpf":
        return make_filter("cpf", world, outlier_log_evidence=outlier_log_evidence)
    if spec.kind == "am":
        manifold = _analytic(settings.object, settings.sensors, settings.am_dtheta_deg)
    elif spec.kind == "rs":
        manifold = _rejection(settings.object, settings.sensors, settings.rs_size,
                              settings.rs_epsilon_m, study_seed)
    elif spec.kind == "tr":
        starts = world.sample_gaussian(mean, std, settings.tr_rollouts, rng=rng)
        manifold = TrajectoryRolloutManifold(world, starts, action, settings.updates,
                                             per_rollout=settings.tr_per_rollout, rng=rng)
    else:
        raise ValueError(f"unknown filter kind {spec.kind!r}")
    phi = settings.mixing_rate if spec.mixing_rate is None else spec.mixing_rate
    return make_filter("mpf", world, manifold, dual_particles=settings.dual_particles,
                       mixing_rate=phi, dual_share=dual_share,
                       outlier_log_evidence=outlier_log_evidence)


def condition_trial(condition: Condition, seed: int, trial: int) -> TrialResult:
    """Trial ``trial`` of a condition in a worker: the condition's shared manifold
    representations built once per process (cached), then :func:`run_trial`."""
    _warm(condition, seed)
    return run_trial(condition.settings, condition.filters, seed, trial)


def _warm(condition: Condition, seed: int) -> None:
    """Build the shared manifold representations once per process."""
    s = condition.settings
    kinds = {f.kind for f in condition.filters}
    if "am" in kinds:
        _analytic(s.object, s.sensors, s.am_dtheta_deg)
    if "rs" in kinds:
        _rejection(s.object, s.sensors, s.rs_size, s.rs_epsilon_m, seed)


# ----------------------------------------------------------------------------- aggregation

def _mean_ci(values: np.ndarray) -> tuple[float, float]:
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return float("nan"), float("nan")
    return float(values.mean()), half_width(values)


def summarise(condition: Condition, results: list[TrialResult]) -> dict:
    """Per filter: post-contact RMSE (cm, deg; mean and 95 % half-width over trials) and,
    for MPF variants, the sampling-failure rate over contact observations after contact."""
    touched = [r for r in results if r.contact_index is not None]
    out = {}
    for f, spec in enumerate(condition.filters):
        pos = [r.rmse_m[f, r.contact_index + 1:].mean() * 100 for r in touched
               if r.contact_index + 1 < r.rmse_m.shape[1]]
        ang = [np.rad2deg(r.rmse_rad[f, r.contact_index + 1:].mean()) for r in touched
               if r.contact_index + 1 < r.rmse_m.shape[1]]
        pos_mean, pos_ci = _mean_ci(pos)
        ang_mean, ang_ci = _mean_ci(ang)
        entry = {"post_contact_rmse_cm": pos_mean, "post_contact_rmse_cm_ci95": pos_ci,
                 "post_contact_rmse_deg": ang_mean, "post_contact_rmse_deg_ci95": ang_ci}
        if spec.kind != "cpf":
            observed = np.concatenate([r.contact_observed[f, r.contact_index:]
                                       for r in touched]) if touched else np.zeros(0, bool)
            fails = np.concatenate([r.sampling_failed[f, r.contact_index:]
                                    for r in touched]) if touched else np.zeros(0, bool)
            entry["sampling_failure_rate"] = (float(fails.sum() / observed.sum())
                                              if observed.sum() else float("nan"))
            correct = np.concatenate([r.reading_correct[r.contact_index:] for r in touched]
                                     ) if touched else np.zeros(0, bool)
            on_correct = observed & correct
            entry["sampling_failure_rate_correct_readings"] = (
                float((fails & on_correct).sum() / on_correct.sum()) if on_correct.sum()
                else float("nan"))
            entry["mixing_rate"] = (condition.settings.mixing_rate if spec.mixing_rate is None
                                    else spec.mixing_rate)
        out[spec.label] = entry
    return {"name": condition.name, "trials": len(results),
            "trials_with_contact": len(touched), "filters": out,
            "parameters": _parameters(condition.settings), **condition.extra}


def _parameters(settings: TrialSettings) -> dict:
    p = asdict(settings)
    p["std_m_m_rad"] = p.pop("std")
    return p


# -------------------------------------------------------------------------------- the parts

def conditions_for(part: str, base: TrialSettings) -> list[Condition]:
    """The conditions (settings x filters) of a part."""
    cpf, am = FilterSpec("cpf", "cpf"), FilterSpec("mpf-am", "am")
    if part == "compare":
        return [Condition("compare", base, (cpf, am))]
    if part == "resolution":
        return [Condition(f"resolution-{r}", replace(base, sensors=r), (cpf, am),
                          {"sensors": r}) for r in RESOLUTIONS]
    if part == "rate":
        return [Condition(f"rate-{int(d * 1000)}mm", replace(base, update_interval_m=d),
                          (cpf, am), {"update_interval_m": d}) for d in UPDATE_INTERVALS_M]
    if part == "representations":
        return [Condition("representations", base,
                          (cpf, am, FilterSpec("mpf-rs", "rs"), FilterSpec("mpf-tr", "tr")))]
    if part == "mixing":
        mixes = tuple(FilterSpec(f"mpf-am-phi{phi:g}", "am", phi) for phi in MIXING_RATES)
        return [Condition("mixing", base, (cpf, *mixes))]
    raise ValueError(f"unknown part {part!r}; choose from {', '.join(PARTS)}, all")


def run_part(part: str, base: TrialSettings, trials: int, seed: int, out: Path, *,
             backend: Backend = Backend(), resume: bool = False,
             progress: bool = True) -> dict:
    """Run a part's trials on ``backend`` (each kept in ``out/trials.jsonl`` as it
    finishes; ``resume`` runs only the missing ones), write ``out/summary.json`` and its
    figures, return the summary."""
    if trials < 2:
        raise ValueError(f"--trials must be at least 2 (for confidence intervals), got {trials}")
    conditions = conditions_for(part, base)
    store = TrialStore(out, f"mpf/{part}", {"trial": asdict(base), "seed": seed},
                       resume=resume)
    jobs = [Job(f"{c.name}/{i}", (c, seed, i)) for c in conditions for i in range(trials)]
    results = map_trials(condition_trial, jobs, backend=backend, store=store,
                         desc=f"mpf {part}", progress=progress)
    runs = [(c, results[k * trials:(k + 1) * trials]) for k, c in enumerate(conditions)]
    summary = {"part": part, "seed": seed, "trials": trials,
               "conditions": [summarise(c, r) for c, r in runs]}
    if len(runs) == 1:
        summary["filters"] = summary["conditions"][0]["filters"]
        summary["parameters"] = summary["conditions"][0]["parameters"]
    else:
        summary["filters"] = {f"{label}@{c['name']}": v for c in summary["conditions"]
                              for label, v in c["filters"].items()}
    summary["figures"] = plot_part(part, runs, summary["conditions"], out) + [
        plot_world(_world(base.object, base.sensors), out / "world.png")]
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def run_study(part: str, base: TrialSettings, trials: int, seed: int, out: Path, *,
              backend: Backend = Backend(), resume: bool = False,
              progress: bool = True) -> dict:
    """``part`` in PARTS or ``all`` (each part into ``out/<part>/``, one combined summary)."""
    options = {"backend": backend, "resume": resume, "progress": progress}
    if part != "all":
        return run_part(part, base, trials, seed, out, **options)
    summaries = {p: run_part(p, base, trials, seed, out / p, **options) for p in PARTS}
    out.mkdir(parents=True, exist_ok=True)
    combined = {"part": "all", "seed": seed, "trials": trials, "parts": summaries}
    (out / "summary.json").write_text(json.dumps(combined, indent=2) + "\n")
    return combined
