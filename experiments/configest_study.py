"""Robot configuration estimation: CPF against the MPF with implicit manifolds (thesis
sec. 5.4, Fig. 5.3 a-c).

Per arm (2-DOF, 3-DOF, WAM) and trial: one simulated experiment (a fresh encoder offset,
the arm file's commanded trajectory), then every filter on the same readings: the CPF
(n = 250) and the MPF with uniform, particle and ball projection (and the explicit
manifold at 2-DOF), n = 250 as n_c = 225 propagated plus n_d = 25 dual particles with
mixing rate 0.1 (the split of the thesis' real-robot experiments, sec. 4.4: the thesis
does not restate it for ch. 5). Error: the weighted joint-space RMSE of the belief's
configurations (each particle projected out of penetration) against the true
configuration (rad, angles wrapped; sec. 4.3.1) after every update.

``summary.json``: ``arms: {arm: {filter: {rmse_rad_mean, rmse_rad_mean_ci95,
rmse_rad_final, rmse_rad_final_ci95, update_ms_median[, projection_failure_rate]}}}``,
per-step mean curves with their 95 % half-widths, and the hypotheses H1-H4 of sec. 5.4
judged on the mean RMSE.
"""

from __future__ import annotations

import json
import time
import zlib
from dataclasses import asdict, dataclass
from functools import lru_cache, partial
from pathlib import Path

import numpy as np

from estimation.configuration.belief import joint_rmse
from estimation.configuration.history import (
    ReadingHistory,
    check_dual_density,
    dual_ball_radius,
)
from estimation.configuration.lift import check_dual_lift, make_dual_lift
from estimation.configuration.manifold import (
    ExplicitTwoLinkManifold,
    ProjectionManifold,
    ProjectionStats,
    check_metric,
)
from estimation.configuration.projection import CONSTRAINTS, METHODS
from estimation.configuration.proprioception import check_proprioception, weigh_encoder_step
from estimation.particles.belief import ParticleBelief
from estimation.particles.factory import make_filter
from estimation.particles.filters import DUAL_SHARES
from experiments.runner import Backend, Job, TrialStore, map_trials
from experiments.statistics import half_width
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld
from models.settings import check_ranges

ARMS = ("2dof", "3dof", "wam")
FILTERS = ("cpf", "mpf-uniform", "mpf-particle", "mpf-ball", "mpf-explicit")
EXPLICIT_ARMS = ("2dof",)


@dataclass(frozen=True)
class ConfigestSettings:
    """The study's settings.

    Attributes:
        arms: which arms (names or arm files).
        trials: experiments per arm.
        seed: study seed; trial j of arm a is seeded from (seed, a, j).
        particles: n, the particle count of every filter (the MPF's n_c + n_d).
        dual_particles: the MPF's n_d.
        mixing_rate: the MPF's phi.
        process_noise_radius_rad: the filters' per-step motion noise (rad).
        method: the projection's root finder, ``lm`` or ``gd`` (thesis).
        ball_radius_rad: MPF-Ball's r_b (None: three kernel bandwidths, sec. 5.2).
        constraints: the projection's constraint set, ``active`` (eq. 5.1) or ``full``
            (see :mod:`estimation.configuration.projection`).
        dual_share: the MPF's split between its sets, ``fixed`` (Alg. 4.2), ``density`` or
            ``evidence``
            (see :class:`estimation.particles.filters.ManifoldParticleFilter`).
        metric: the particle and ball projections' metric, ``joint`` (sec. 5.2) or
            ``kernel`` (see :mod:`estimation.configuration.manifold`).
        proprioception: what every filter takes from the encoders, ``first`` (their
            first reading) or ``steps`` (also each step's motion; see
            :mod:`estimation.configuration.proprioception`).
        dual_density: how the MPFs weigh their duals, ``kernel`` (sec. 4.2.3) or
            ``history`` (see :mod:`estimation.configuration.history`).
        dual_lift: where the MPFs' duals sit, ``surface`` (sec. 5.2), ``normal`` or
            ``normal-refined`` (lifted to the commanded side; see
            :mod:`estimation.configuration.lift`).
    """

    arms: tuple[str, ...] = ARMS
    trials: int = 100
    seed: int = 0
    particles: int = 250
    dual_particles: int = 25
    mixing_rate: float = 0.1
    process_noise_radius_rad: float = 0.01
    method: str = "lm"
    ball_radius_rad: float | None = None
    constraints: str = "active"
    dual_share: str = "fixed"
    metric: str = "joint"
    proprioception: str = "first"
    dual_density: str = "kernel"
    dual_lift: str = "surface"

    def __post_init__(self):
        if self.trials < 2:
            raise ValueError(f"trials must be >= 2 (for intervals), got {self.trials}")
        if not 0 < self.dual_particles < self.particles:
            raise ValueError("dual_particles must be in (0, particles)")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got "
                             f"{self.method!r}")
        if not 0.0 <= self.mixing_rate <= 1.0:
            raise ValueError(f"mixing_rate must be in [0, 1], got {self.mixing_rate}")
        check_ranges(self, positive=("ball_radius_rad",),
                     non_negative=("process_noise_radius_rad",),
                     at_most={"ball_radius_rad": np.pi, "process_noise_radius_rad": np.pi})
        if self.constraints not in CONSTRAINTS:
            raise ValueError(f"constraints must be one of {', '.join(CONSTRAINTS)}, got "
                             f"{self.constraints!r}")
        check_metric(self.metric, self.ball_radius_rad)
        check_proprioception(self.proprioception)
        if self.dual_share not in DUAL_SHARES:
            raise ValueError(f"dual_share must be one of {', '.join(DUAL_SHARES)}, got "
                             f"{self.dual_share!r}")
        check_dual_density(self.dual_density, self.metric, self.dual_share)
        check_dual_lift(self.dual_lift)


def filters_for(arm: str) -> tuple[str, ...]:
    """The filters compared on ``arm`` (MPF-Explicit only where the manifold is known)."""
    return tuple(f for f in FILTERS if f != "mpf-explicit" or arm in EXPLICIT_ARMS)


@lru_cache(maxsize=4)
def arm_world(arm: str, process_noise_radius_rad: float) -> ArmWorld:
    """The arm's world, built once per process (a Drake plant does not pickle)."""
    return ArmWorld(ArmSpec.load(arm), process_noise_radius_rad=process_noise_radius_rad)


@dataclass(frozen=True)
class TrialResult:
    """One experiment: per filter, the RMSE after each update (rad) and what it cost.

    Attributes:
        rmse_rad: {filter: (T,) RMSE}.
        update_ms: {filter: median update time (ms)}.
        projection: {filter: (seeds, failures)} for the MPF variants.
        contact_steps: updates with any contact reading.
    """

    rmse_rad: dict[str, np.ndarray]
    update_ms: dict[str, float]
    projection: dict[str, tuple[int, int]]
    contact_steps: int


@dataclass(frozen=True)
class FilterRun:
    """One filter along one experiment.

    Attributes:
        rmse_rad: (T,) joint-space RMSE after each update (rad).
        update_ms: (T,) wall time of each update (ms).
        projection: the manifold's counts (None for the CPF).
    """

    rmse_rad: np.ndarray
    update_ms: np.ndarray
    projection: ProjectionStats | None


def build_filter(world: ArmWorld, kind: str, settings: ConfigestSettings, *,
                 outlier_log_evidence: float | None = None):
    """Filter ``kind`` (one of :data:`FILTERS`) for ``world``: the filter, the particles
    it propagates (the MPF's n_c) and its manifold (None for the CPF); with
    ``outlier_log_evidence``, the filter's outlier gate (the study's filters have none)."""
    if kind == "cpf":
        return (make_filter("cpf", world, outlier_log_evidence=outlier_log_evidence),
                settings.particles, None)
    strategy = kind.split("-", 1)[1]
    manifold = (ExplicitTwoLinkManifold(world) if strategy == "explicit" else
                ProjectionManifold(world, strategy=strategy, method=settings.method,
                                   ball_radius_rad=dual_ball_radius(
                                       world, settings.dual_density, settings.ball_radius_rad),
                                   constraints=settings.constraints,
                                   metric=settings.metric))
    filt = make_filter("mpf", world, manifold, dual_particles=settings.dual_particles,
                       mixing_rate=settings.mixing_rate, dual_share=settings.dual_share,
                       outlier_log_evidence=outlier_log_evidence,
                       dual_lift=make_dual_lift(world, settings.dual_lift))
    return filt, settings.particles - settings.dual_particles, manifold


def run_filter(world: ArmWorld, trajectory, kind: str, settings: ConfigestSettings, *,
               rng: np.random.Generator) -> FilterRun:
    """Filter ``kind`` (one of :data:`FILTERS`) along one simulated experiment."""
    filt, n, manifold = build_filter(world, kind, settings)
    belief = ParticleBelief.uniform(
        world.initial_belief_states(trajectory.encoders[0], n, rng=rng), world.angular)
    rmse, times = [], []
    # the commanded configurations relative to the start: all the history needs
    commanded = np.cumsum(trajectory.commanded, axis=0)
    history = (ReadingHistory.begin(trajectory.encoders[0], np.zeros(world.dof),
                                    world.sensor_count)
               if manifold is not None and settings.dual_density == "history" else None)
    for t, action in enumerate(trajectory.commanded):
        start = time.perf_counter()
        readings = trajectory.contacts[t + 1]
        if history is None:
            belief, _ = filt.update(belief, action, readings, rng=rng)
        else:
            belief, diagnostics = filt.update(belief, action, readings, rng=rng,
                                              dual_log_density=partial(
                                                  history.log_density, world,
                                                  commanded=commanded[t]))
            if not diagnostics.rejected:
                history = history.appended(commanded[t], readings)
        if settings.proprioception == "steps":
            belief = weigh_encoder_step(world, belief, action, world.angle_difference(
                trajectory.encoders[t + 1], trajectory.encoders[t]))
        times.append(time.perf_counter() - start)
        rmse.append(joint_rmse(world, belief, trajectory.q_true[t + 1]))
    return FilterRun(np.array(rmse), np.array(times) * 1e3,
                     None if manifold is None else manifold.stats)


def arm_key(arm: str) -> int:
    """A seed component per arm that does not depend on which arms a study runs: the
    built-in arm's index, or a checksum of another file's name."""
    return ARMS.index(arm) if arm in ARMS else zlib.crc32(str(arm).encode())


def run_trial(arm: str, trial: int, settings: ConfigestSettings) -> TrialResult:
    """Trial ``trial`` of ``arm``: one experiment, every filter on it (seeded from
    ``(seed, arm_key(arm), trial)``)."""
    world = arm_world(arm, settings.process_noise_radius_rad)
    key = arm_key(arm)
    trajectory = world.simulate(rng=np.random.default_rng((settings.seed, key, trial)))
    rmse, ms, projection = {}, {}, {}
    for f, kind in enumerate(filters_for(arm)):
        rng = np.random.default_rng((settings.seed, key, trial, 1 + f))
        run = run_filter(world, trajectory, kind, settings, rng=rng)
        rmse[kind], ms[kind] = run.rmse_rad, float(np.median(run.update_ms))
        if run.projection is not None:
            projection[kind] = (run.projection.seeds, run.projection.failures)
    return TrialResult(rmse, ms, projection, int(trajectory.contacts[1:].any(axis=1).sum()))


def trial_jobs(settings: ConfigestSettings) -> list[Job]:
    """The study's trials, keyed ``arm/trial``."""
    return [Job(f"{arm}/{j}", (arm, j, settings)) for arm in settings.arms
            for j in range(settings.trials)]


def trial_store(settings: ConfigestSettings, out: Path, *, resume: bool) -> TrialStore:
    """``out/trials.jsonl``, keyed by every setting a trial's result depends on (not the
    arms or the trial count, which only choose trials: a resumed study may add some)."""
    relevant = {k: v for k, v in asdict(settings).items() if k not in ("arms", "trials")}
    return TrialStore(out, "configest", relevant, resume=resume)


def summarise_arm(arm: str, results: list[TrialResult]) -> dict:
    """Per filter: mean and final RMSE over trials with 95 % half-widths, the update time,
    the projection failure rate, and the mean curve; for the MPF variants also the paired
    difference to the CPF (``vs_cpf_rad_mean``, ``vs_cpf_rad_final`` with ``_ci95``: every
    filter runs on the same experiments, so the per-experiment difference removes the
    spread between experiments that the unpaired intervals carry) and, in
    ``paired_rad_mean``, that of the mean RMSE to every other filter (``{other: {diff,
    ci95}}``, this filter minus the other, rad)."""
    out = {}
    cpf = np.array([r.rmse_rad["cpf"] for r in results])
    per_trial_mean = {kind: np.array([r.rmse_rad[kind] for r in results]).mean(axis=1)
                      for kind in filters_for(arm)}
    for kind in filters_for(arm):
        curves = np.array([r.rmse_rad[kind] for r in results])  # (trials, T)
        means, finals = curves.mean(axis=1), curves[:, -1]
        entry = {
            "rmse_rad_mean": float(means.mean()), "rmse_rad_mean_ci95": half_width(means),
            "rmse_rad_final": float(finals.mean()),
            "rmse_rad_final_ci95": half_width(finals),
            "update_ms_median": float(np.median([r.update_ms[kind] for r in results])),
            "curve_rad": [round(float(v), 5) for v in curves.mean(axis=0)],
            "curve_rad_ci95": [round(half_width(curves[:, t]), 5)
                               for t in range(curves.shape[1])],
        }
        if kind != "cpf":
            seeds = sum(r.projection[kind][0] for r in results)
            failures = sum(r.projection[kind][1] for r in results)
            entry["projection_failure_rate"] = failures / seeds if seeds else 0.0
            diff = curves - cpf
            entry["vs_cpf_rad_mean"] = float(diff.mean())
            entry["vs_cpf_rad_mean_ci95"] = half_width(diff.mean(axis=1))
            entry["vs_cpf_rad_final"] = float(diff[:, -1].mean())
            entry["vs_cpf_rad_final_ci95"] = half_width(diff[:, -1])
            entry["paired_rad_mean"] = {
                other: {"diff": float((means - theirs).mean()),
                        "ci95": half_width(means - theirs)}
                for other, theirs in per_trial_mean.items() if other != kind}
        out[kind] = entry
    return out


def _better(a: dict, b: dict) -> bool:
    """``a``'s mean RMSE is below ``b``'s, beyond both 95 % intervals."""
    return a["rmse_rad_mean"] + a["rmse_rad_mean_ci95"] < \
        b["rmse_rad_mean"] - b["rmse_rad_mean_ci95"]


def _overlap(a: dict, b: dict, key: str = "rmse_rad_mean") -> bool:
    """The 95 % intervals of ``a[key]`` and ``b[key]`` overlap."""
    return abs(a[key] - b[key]) <= a[key + "_ci95"] + b[key + "_ci95"]


def _paired_below(a: dict, other: str) -> bool:
    """``a``'s mean RMSE is below filter ``other``'s on the same experiments: the paired
    difference's 95 % interval lies below zero."""
    d = a["paired_rad_mean"][other]
    return d["diff"] + d["ci95"] < 0


def hypotheses(arms: dict) -> dict:
    """H1-H4 of thesis sec. 5.4, judged on the mean RMSE and its 95 % intervals.

    Every filter runs on the same experiments, so H1, H3 and H4 are judged on the paired
    per-experiment differences; each has an ``_unpaired`` twin judged on the filters'
    own intervals, a stricter test that the spread between experiments can hide a
    consistent difference from. H1: some MPF beats the CPF on every arm. H2: at 2-DOF
    every MPF variant's interval overlaps every other's (``H2_alike_at_2dof_final``: the
    same on the final-step RMSE; the thesis judges H2 by eye on Fig. 5.3a, "all variants
    of the MPF performed similarly", which may mean either). H3: particle and ball
    projection beat uniform at 3-DOF and on the WAM. H4: ball projection is the best on
    the WAM, or no other variant is below it beyond the interval. Arms not run are left
    out.
    """
    out = {}
    mpfs = {arm: {k: v for k, v in f.items() if k != "cpf"} for arm, f in arms.items()}
    out["H1_mpf_beats_cpf"] = {arm: any(v["vs_cpf_rad_mean"] + v["vs_cpf_rad_mean_ci95"] < 0
                                        for v in mpfs[arm].values()) for arm in arms}
    out["H1_mpf_beats_cpf_unpaired"] = {arm: any(_better(v, arms[arm]["cpf"])
                                                 for v in mpfs[arm].values())
                                        for arm in arms}
    if "2dof" in arms:
        v = list(mpfs["2dof"].values())
        out["H2_alike_at_2dof"] = all(_overlap(a, b) for a in v for b in v)
        out["H2_alike_at_2dof_final"] = all(_overlap(a, b, "rmse_rad_final")
                                            for a in v for b in v)
    high = [a for a in ("3dof", "wam") if a in arms]
    focused = ("mpf-particle", "mpf-ball")
    out["H3_particle_ball_beat_uniform"] = {
        arm: all(_paired_below(arms[arm][k], "mpf-uniform") for k in focused)
        for arm in high}
    out["H3_particle_ball_beat_uniform_unpaired"] = {
        arm: all(_better(arms[arm][k], arms[arm]["mpf-uniform"]) for k in focused)
        for arm in high}
    if "wam" in arms:
        ball = mpfs["wam"]["mpf-ball"]
        out["H4_ball_best_on_wam"] = not any(
            _paired_below(v, "mpf-ball") for k, v in mpfs["wam"].items() if k != "mpf-ball")
        best = min(mpfs["wam"].values(), key=lambda e: e["rmse_rad_mean"])
        out["H4_ball_best_on_wam_unpaired"] = best is ball or _overlap(best, ball)
    return out


def run_study(settings: ConfigestSettings, out: Path, *, backend: Backend = Backend(),
              resume: bool = False, progress: bool = True) -> dict:
    """Run every arm's trials on ``backend`` (each kept in ``out/trials.jsonl`` as it
    finishes; ``resume`` runs only the missing ones), write ``summary.json`` and
    ``configest.png`` into ``out``."""
    from experiments.configest_plots import plot_rmse

    store = trial_store(settings, out, resume=resume)
    jobs = trial_jobs(settings)
    results = map_trials(run_trial, jobs, backend=backend, store=store, desc="configest",
                         progress=progress)
    arms = {}
    for arm in settings.arms:
        mine = [r for job, r in zip(jobs, results, strict=True) if job.args[0] == arm]
        arms[arm] = summarise_arm(arm, mine)
        arms[arm]["contact_steps_mean"] = float(np.mean([r.contact_steps for r in mine]))
    filters = {a: {k: v for k, v in f.items() if isinstance(v, dict)} for a, f in arms.items()}
    summary = {"settings": asdict(settings), "arms": arms,
               "hypotheses": hypotheses(filters),
               "figures": [plot_rmse(filters, out / "configest.png")]}
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
