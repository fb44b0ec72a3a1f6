"""Seed 003's experiments on the simulated rig: ``cmanip experiment visuotactile``.

Parts (each writes ``DIR/<part>/`` figures; ``DIR/summary.json`` collects them):

- ``noise``: identify the costs' covariances and the limit surface's c from training runs
  (rect1 on plywood, seeds apart from the trials'), check normality (QQ plots);
  writes ``DIR/noise.json``, which every other part then uses (sec. V-B).
- ``methods``: vision only, EKF, iSAM with 1/100/200/1000-step history (Table II) as the
  paper ran it (iSAM1-style batch relinearisation, one pooled stationary prior); iSAM2's
  fluid relinearisation instead (with either prior); and ours, the paper's scheme with the
  contact-aware stationary prior, at 1 and 200 steps.
- ``shapes``: rect1, ellip2, butter (Table III); ``surfaces``: abs, delrin, plywood,
  polyurethane (Table IV).
- ``costs``: vision removed, started at the true pose: motion + contact, contact only,
  motion only (Fig. 8).
- ``timing``: per-update time (mean, p99, max) and batch relinearisation time.

A trial is the standard procedure (Fig. 6) from a jittered start (x, y ~ N(0, 5 mm), theta
~ U(-10, 10) deg) with its own sensor noise; it is reproducible from (seed, trial, object,
surface). Simulated logs are kept in ``DIR/logs/`` and reused by later parts.
"""

from __future__ import annotations

import fcntl
import json
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from estimation.pushing.costs import limit_surface_c
from estimation.pushing.filters import PushingEKF, vision_only
from estimation.pushing.inputs import PushingSteps, rmse
from estimation.pushing.noise import PushingNoise, identify_from_runs
from estimation.pushing.smoother import (
    SmootherSettings,
    VisuoTactileSmoother,
    recommended_settings,
)
from experiments.runner import Backend, Job, map_trials
from models.objects import ObjectSpec
from models.pusher.log import PushLog
from models.pusher.procedure import standard_procedure
from models.pusher.rig import PusherSliderRig
from models.settings import check_ranges

PARTS = ("noise", "methods", "shapes", "surfaces", "costs", "timing")
SHAPES = ("rect1", "ellip2", "butter")
SURFACES = ("abs", "delrin", "plywood", "polyurethane")
#: Seed 003's published RMSE (translation mm, rotation deg), mean +- std.
PAPER_TABLE_II = {"vision only": (15.7, 3.4), "EKF": (6.4, 6.4), "iSAM 1-step": (7.3, 3.7),
                  "iSAM 100-step": (6.3, 2.6), "iSAM 200-step": (6.0, 2.3),
                  "iSAM 1000-step": (6.1, 1.8)}
PAPER_TABLE_III = {"rect1": (6.0, 2.3), "ellip2": (7.3, 5.7), "butter": (12.0, 12.1)}
PAPER_TABLE_IV = {"abs": (5.6, 3.7), "delrin": (8.7, 3.0), "plywood": (6.0, 2.3),
                  "polyurethane": (5.1, 1.9)}
#: Seeds of the noise-identification runs are offset by this from the trials'.
TRAINING_SEED_OFFSET = 100_000


@dataclass(frozen=True)
class VisuotactileSettings:
    """Attributes:
        trials: runs per condition. seed: the study's seed. noise_trials: training runs for
        the ``noise`` part. rig: the rig file. history: the smoother's default history.
    """

    trials: int = 10
    seed: int = 0
    noise_trials: int = 3
    rig: str | None = None
    history: int = 200

    def __post_init__(self):
        check_ranges(self, counts=("trials", "noise_trials", "history"))

    def load_rig(self) -> PusherSliderRig:
        return PusherSliderRig.load(self.rig) if self.rig else PusherSliderRig.load()


def trial_seed(seed: int, trial: int, object_name: str, surface: str) -> int:
    """A stable seed for one (trial, object, surface) of a study seeded ``seed``."""
    return zlib.crc32(f"{seed}/{trial}/{object_name}/{surface}".encode())


def log_path(settings: VisuotactileSettings, object_name: str, surface: str, trial: int,
             logs: Path, *, training: bool = False) -> Path:
    """Where the log of one trial is kept."""
    seed = settings.seed + (TRAINING_SEED_OFFSET if training else 0)
    return logs / f"{'train_' if training else ''}{object_name}_{surface}_{seed}_{trial}.csv"


def simulated_log_file(settings: VisuotactileSettings, object_name: str, surface: str,
                       trial: int, logs: str, training: bool = False) -> str:
    """The path of one trial's log, simulated first unless already there (a trial of the
    trial runner: the logs directory is the study's store)."""
    path = log_path(settings, object_name, surface, trial, Path(logs), training=training)
    if not path.is_file():
        simulated_log(settings, object_name, surface, trial, Path(logs), training=training)
    return str(path)


def simulated_logs(settings: VisuotactileSettings, object_name: str, surface: str,
                   logs: Path, *, count: int, training: bool = False,
                   backend: Backend = Backend(), progress: bool = True) -> list[PushLog]:
    """``count`` trials' logs, the missing ones simulated on ``backend`` (Drake, about a
    minute each) and every one read from ``logs``."""
    jobs = [Job(f"{object_name}/{surface}/{i}",
                (settings, object_name, surface, i, str(logs), training))
            for i in range(count)]
    paths = map_trials(simulated_log_file, jobs, backend=backend,
                       desc=f"simulating {'training ' if training else ''}"
                            f"{object_name}/{surface}", progress=progress)
    return [PushLog.read(Path(path)) for path in paths]


def simulated_log(settings: VisuotactileSettings, object_name: str, surface: str, trial: int,
                  logs: Path, *, training: bool = False) -> PushLog:
    """The log of one trial, simulated (and written to ``logs``) unless already there."""
    seed = settings.seed + (TRAINING_SEED_OFFSET if training else 0)
    path = log_path(settings, object_name, surface, trial, logs, training=training)
    if path.is_file():
        return PushLog.read(path)
    from diagrams.pusher.simulation import simulate_push  # Drake only when simulating

    rng = np.random.default_rng(trial_seed(seed, trial, object_name, surface))
    start = np.array([rng.normal(0, 0.005), rng.normal(0, 0.005),
                      np.deg2rad(rng.uniform(-10, 10))])
    rig = settings.load_rig().with_surface(surface)
    run = simulate_push(rig, ObjectSpec.load(object_name), standard_procedure(),
                        seed=int(rng.integers(2**31)), object_name=object_name,
                        initial_pose=start)
    logs.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".part")  # a killed run leaves no half log
    run.log.write(partial)
    partial.replace(path)
    return run.log


# -- methods
@dataclass(frozen=True)
class Method:
    """An estimator to compare: ``kind`` is vision, ekf or isam."""

    label: str
    kind: str
    smoother: SmootherSettings = SmootherSettings()
    contact_aware: bool = False


def improved(history: int) -> Method:
    """Our variant: the paper's scheme with the contact-aware stationary prior."""
    return Method(f"iSAM {history}-step, contact-aware prior (ours)", "isam",
                  recommended_settings(history))


def paper_methods(history: int = 200) -> tuple[Method, ...]:
    """Table II's rows (as the paper ran them); iSAM2's fluid relinearisation instead of
    the batch one; and ours (the contact-aware stationary prior) at 1 and 200 steps."""
    return (Method("vision only", "vision"), Method("EKF", "ekf"),
            *(Method(f"iSAM {h}-step", "isam", SmootherSettings(history=h))
              for h in (1, 100, 200, 1000)),
            Method(f"iSAM {history}-step, fluid relinearisation", "isam",
                   SmootherSettings(history=history, relinearization="fluid")),
            Method(f"iSAM {history}-step, fluid + contact-aware", "isam",
                   SmootherSettings(history=history, relinearization="fluid",
                                    stationary="contact-aware")),
            improved(1), improved(history))


def estimate(method: Method, steps: PushingSteps, polygon: np.ndarray, noise: PushingNoise,
             *, start: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """(K, 3) estimates and timing (ms) of one method on one run."""
    if method.kind == "vision":
        return vision_only(steps), {}
    if method.kind == "ekf":
        ekf = PushingEKF(polygon, noise, rod_radius_m=steps.rod_radius_m,
                         contact_aware=method.contact_aware)
        begin = time.perf_counter()
        out = ekf.run(steps, start=start)
        return out, {"step_ms_mean": (time.perf_counter() - begin) * 1e3 / len(steps)}
    smoother = VisuoTactileSmoother(polygon, noise, method.smoother,
                                    rod_radius_m=steps.rod_radius_m)
    try:
        out = smoother.run(steps, start=start)
    except RuntimeError as err:  # GTSAM: an under-determined graph (e.g. costs removed)
        return np.full((len(steps), 3), np.nan), {"failed": str(err).strip().splitlines()[0]}
    return out, timing_of(smoother)


def timing_of(smoother: VisuoTactileSmoother) -> dict:
    """Per-update and relinearisation times (ms) of a finished run."""
    updates = np.array(smoother.update_seconds) * 1e3
    rebuilds = np.array(smoother.rebuild_seconds) * 1e3
    out = {"update_ms_mean": float(updates.mean()),
           "update_ms_p99": float(np.percentile(updates, 99)),
           "update_ms_max": float(updates.max())}
    if len(rebuilds):
        out |= {"relinearize_ms_mean": float(rebuilds.mean()),
                "relinearize_ms_max": float(rebuilds.max())}
    return out


def _stats(values: list[float]) -> dict:
    v = np.array(values, dtype=float)
    ok = v[np.isfinite(v)]
    if not len(ok):
        return {"mean": None, "std": None, "failed_trials": len(v)}
    return {"mean": float(ok.mean()), "std": float(ok.std(ddof=1)) if len(ok) > 1 else 0.0,
            "failed_trials": int(len(v) - len(ok))}


def compare(methods: tuple[Method, ...], logs: list[PushLog], polygon: np.ndarray,
            noise: PushingNoise, *, start_at_truth: bool = False,
            progress: bool = True, label: str = "") -> tuple[dict, dict]:
    """Run every method on every log.

    Returns:
        (summary per method: ``rmse_mm``/``rmse_deg`` {mean, std}, per-trial values and
        timing; traces of trial 0: t and each method's estimates, and the truth).
    """
    per = {m.label: {"mm": [], "deg": [], "timing": []} for m in methods}
    traces: dict = {}
    jobs = [(m, i, log) for i, log in enumerate(logs) for m in methods]
    for method, i, log in tqdm(jobs, desc=label or "estimating", disable=not progress):
        steps = PushingSteps.from_log(log)
        start = steps.truth[0] if start_at_truth else None
        estimates, timing = estimate(method, steps, polygon, noise, start=start)
        mm, deg = rmse(estimates, steps.truth)
        per[method.label]["mm"].append(mm)
        per[method.label]["deg"].append(deg)
        per[method.label]["timing"].append(timing)
        if i == 0:
            traces["t"] = steps.t
            traces["truth"] = steps.truth
            traces[method.label] = estimates
    summary = {}
    for label_, values in per.items():
        summary[label_] = {"rmse_mm": _stats(values["mm"]), "rmse_deg": _stats(values["deg"]),
                           "per_trial_mm": values["mm"], "per_trial_deg": values["deg"]}
        timings = [t for t in values["timing"] if t and "failed" not in t]
        if timings:
            summary[label_]["timing"] = {k: float(np.mean([t[k] for t in timings]))
                                         for k in timings[0]}
        failures = [t["failed"] for t in values["timing"] if t and "failed" in t]
        if failures:
            summary[label_]["failures"] = failures
    return summary, traces


# -- parts
def noise_model(settings: VisuotactileSettings, out: Path, progress: bool = True, *,
                backend: Backend = Backend()) -> tuple[PushingNoise, dict]:
    """Identify (or load ``out/noise.json``) the noise model from training runs."""
    path = out / "noise.json"
    logs = simulated_logs(settings, "rect1", "plywood", out / "logs",
                          count=settings.noise_trials, training=True, backend=backend,
                          progress=progress)
    runs = [PushingSteps.from_log(log) for log in logs]
    noise, residuals, c = identify_from_runs(runs, ObjectSpec.load("rect1").footprint())
    if path.is_file():
        return PushingNoise.load(path), {"residuals": residuals, "c_m": c}
    out.mkdir(parents=True, exist_ok=True)
    noise.save(path)
    return noise, {"residuals": residuals, "c_m": c}


def run_part(part: str, settings: VisuotactileSettings, out: Path,
             progress: bool = True, *, backend: Backend = Backend()) -> dict:
    """Run one part; returns its summary (also merged into ``out/summary.json``). The
    push simulations run on ``backend`` (their logs kept in ``out/logs``, so a killed study
    simulates only what is missing); the estimators run here, one after another, so that
    their timings are of an otherwise idle process."""
    from experiments import visuotactile_plots as plots

    if part not in PARTS:
        raise ValueError(f"unknown part {part!r}; one of {', '.join(PARTS)} or all")
    noise, identification = noise_model(settings, out, progress, backend=backend)
    folder = out / part
    folder.mkdir(parents=True, exist_ok=True)
    logs_dir = out / "logs"

    def trials(object_name="rect1", surface="plywood"):
        return simulated_logs(settings, object_name, surface, logs_dir,
                              count=settings.trials, backend=backend, progress=progress)

    rect1 = ObjectSpec.load("rect1").footprint()
    if part == "noise":
        summary = {"c_m": identification["c_m"],
                   "c_uniform_pressure_m": limit_surface_c(rect1),
                   "training_runs": settings.noise_trials, "noise": noise.to_json(),
                   "figures": plots.noise_figures(identification["residuals"], folder)}
    elif part == "methods":
        methods = paper_methods(settings.history)
        results, traces = compare(methods, trials(), rect1, noise, progress=progress,
                                  label="methods")
        summary = {"methods": results, "paper": PAPER_TABLE_II,
                   "figures": plots.methods_figures(results, traces, PAPER_TABLE_II, folder)}
    elif part in ("shapes", "surfaces"):
        methods = (Method("vision only", "vision"),
                   Method(f"iSAM {settings.history}-step", "isam",
                          SmootherSettings(history=settings.history)),
                   improved(settings.history))
        conditions = ([(name, "plywood") for name in SHAPES] if part == "shapes"
                      else [("rect1", surface) for surface in SURFACES])
        results = {}
        for object_name, surface in conditions:
            key = object_name if part == "shapes" else surface
            polygon = ObjectSpec.load(object_name).footprint()
            results[key], _ = compare(methods, trials(object_name, surface), polygon, noise,
                                      progress=progress, label=key)
        paper = PAPER_TABLE_III if part == "shapes" else PAPER_TABLE_IV
        summary = {"conditions": results, "paper_isam": paper,
                   "figures": [plots.conditions_figure(results, paper, part, folder)]}
    elif part == "costs":
        methods = tuple(
            Method(label, "isam", SmootherSettings(history=settings.history,
                                                   costs=costs + ("stationary",)))
            for label, costs in (("motion + contact", ("motion", "contact")),
                                 ("contact only", ("contact",)),
                                 ("motion only", ("motion",))))
        results, traces = compare(methods, trials(), rect1, noise, start_at_truth=True,
                                  progress=progress, label="costs")
        summary = {"methods": results, "vision": "removed; started at the true pose",
                   "figures": [plots.error_figure(traces, "costs", folder)]}
    else:  # timing
        methods = tuple(Method(f"iSAM {h}-step", "isam", SmootherSettings(history=h))
                        for h in (1, 100, 200, 1000))
        results, _ = compare(methods, trials(), rect1, noise, progress=progress,
                             label="timing")
        summary = {"methods": {k: v.get("timing", {}) for k, v in results.items()},
                   "paper": {"update_ms_mean_200_step": "< 1",
                             "relinearize_ms_mean": 28.0, "relinearize_ms_max": 70.0},
                   "figures": [plots.timing_figure(results, folder)]}
    summary["settings"] = {"trials": settings.trials, "seed": settings.seed,
                           "history": settings.history,
                           "rig": settings.rig or "models/assets/pusher_slider.yaml"}
    _merge(out / "summary.json", part, summary)
    return summary


def run_study(part: str, settings: VisuotactileSettings, out: Path,
              progress: bool = True, *, backend: Backend = Backend()) -> dict:
    """Run ``part`` (or ``all``); returns ``{part: summary}``."""
    parts = PARTS if part == "all" else (part,)
    return {p: run_part(p, settings, out, progress, backend=backend) for p in parts}


def _merge(path: Path, part: str, summary: dict) -> None:
    """Add one part to ``summary.json``, under a lock: parts may run as separate processes
    into one directory."""
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        data = json.loads(path.read_text()) if path.is_file() else {}
        data[part] = summary
        path.write_text(json.dumps(data, indent=2, default=_plain))


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} to JSON")
