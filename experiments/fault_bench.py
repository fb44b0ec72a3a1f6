"""Estimators under faults (part of ``cmanip bench robustness``).

Every estimator of the project is run on the same simulated experiment clean and with one
fault injected into its inputs for a stretch of steps, each run of a particle filter with
random numbers of its own. The particle filters run so both as the thesis has them and
robust, with an outlier gate (a reading with evidence log p(o | b+) below
:data:`OUTLIER_GATE` that no dual explains either is propagated through, not weighed) and,
for the MPFs, the evidence split between the sets (:data:`ROBUST_DUAL_SHARE`), each against
its own clean runs. A
fault is *recovered* when the faulty run never produced a non-finite estimate and its
error over the last quarter of the run is at most ``max(1.5 x clean, clean + tol,
worst)``, ``clean`` the median and ``worst`` the largest of that error over
:data:`CLEAN_DRAWS` clean runs of the filter with different random numbers: the estimator
came back to where the clean runs are, give or take what a different draw of the same
filter gives (measured: on the MPF study's first push, MPF-AM's last-quarter error over
eight clean draws spans 0.3 to 3.8 cm). The faulty runs do not share the clean draws'
random numbers (nor each other's), so that a run no fault harmed is one more clean draw,
exchangeable with them: the pooled test :func:`lasting_harm` rests on that.

The rule has a false-alarm rate of its own: a faulty run is, after its stretch, one more
draw of the filter, and a draw with no lasting harm still ends above the largest of
:data:`CLEAN_DRAWS` others about once in ``CLEAN_DRAWS + 1`` (less, for the margins). So
each filter also runs a *sham* (:data:`SHAM`): one more clean draw, judged by the same
rule against the same clean draws; ``sham_recovered`` of ``sham_runs`` is the rate at
which the rule passes a run that no fault touched, the baseline for ``faults_recovered``.

Estimators and faults:

- the hand-relative filters of ch. 4 (CPF, MPF with the AM, RS and TR manifolds) on the
  MPF study's push (:mod:`experiments.mpf_study`), and the configuration filters of ch. 5
  (CPF, MPF-Ball) on the 3-DOF arm (:mod:`experiments.configest_study`), each with
  ``nan-action`` (the hand's measured palm pose or the arm's commanded configuration
  arrives as NaN: the filter skips the update and reports it, and the first finite pose
  after the stretch carries the whole motion since the last one, as
  :class:`estimation.hand.tracker.HandRelativeTracker` and
  :class:`diagrams.herb.configuration.ConfigurationEstimator` do), ``nan-reading`` (the
  contact reading arrives as NaN: the filter propagates without weighting and reports it),
  ``all-sensors-on`` (every sensor lit at once: with the arm's discriminative sensors a
  reading no state explains, whose evidence p(o | b+) falls below :data:`SURPRISE`; with
  the planar world's 10 % flips a plausible one), ``stuck-on`` (one sensor reads contact
  whatever happens), ``stuck-off`` (every sensor reads free during contact) and
  ``contradicting`` (all on, all off, alternating, for twice as long). The faults start
  two steps after the first true contact; tol is 1 cm (hand) and 0.1 rad (arm).
- the visuo-tactile smoother (seed 003) on a simulated push of rect1, with ``nan-force``,
  ``nan-camera`` (both left out and counted in ``rejected_inputs``), ``blind`` (both at
  once: the rods' penetration costs alone keep the object moving), ``teleported-camera``
  (camera poses 30 cm and 1 rad off: no pose explains them; the vision cost's Huber kernel
  bounds their pull), ``dropped-frames`` (no camera frame for the stretch: the tactile
  costs carry the estimate) and ``stuck-contact`` (both force sensors freeze, reading
  contact with the force of the step before); tol is 5 mm.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import lru_cache

import numpy as np
from tqdm import tqdm

from estimation.configuration.belief import joint_rmse
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import SURPRISE
from estimation.pushing.inputs import PushingSteps
from estimation.pushing.noise import identify_from_runs
from estimation.pushing.smoother import VisuoTactileSmoother, recommended_settings
from experiments.configest_study import ConfigestSettings, arm_world, build_filter
from experiments.mpf_study import FilterSpec, TrialSettings, simulate_truth
from experiments.mpf_study import build_filter as build_hand_filter
from experiments.runner import Backend, Job, map_trials
from experiments.statistics import (
    clustered_half_width,
    harmed_share_upper,
    holm,
    rank_sum_p_value,
    wilson_interval,
)
from models.objects import ObjectSpec
from models.planar.world import PlanarWorld
from models.se2 import compose

FILTER_FAULTS = ("nan-action", "nan-reading", "all-sensors-on", "stuck-on", "stuck-off",
                 "contradicting")
SMOOTHER_FAULTS = ("nan-force", "nan-camera", "blind", "teleported-camera",
                   "dropped-frames", "stuck-contact")
SHAM = "none"
"""The control: no fault, a fresh draw judged like the faulty runs."""
FAULT_STEPS = 10
"""Length of a fault (updates); ``contradicting`` lasts twice as long."""
SMOOTHER_FAULT_S = 1.0
"""Length of a smoother fault (s)."""
RECOVERY_FACTOR = 1.5
CLEAN_DRAWS = 11
"""Clean runs of each particle filter per experiment, with different random numbers (eleven:
with five, the 3-DOF CPF's faulty runs ranked 0.70 among them, p 0.004, and 0.54, p 0.26, among
eleven on the same experiments: five clean draws of a filter whose error is bimodal are too
few a reference)."""
REJECTED = {"nan-action": "action", "nan-reading": "observation"}
"""The input a filter must report rejecting under each NaN fault."""
OUTLIER_GATE = -30.0
"""The robust filters' outlier gate on log p(o | b+): about four wrong readings each of
every particle with the arm's error rate 0.001, thirteen with the planar world's 0.1."""
HAND_FILTERS = (FilterSpec("cpf", "cpf"), FilterSpec("mpf-am", "am"),
                FilterSpec("mpf-rs", "rs"), FilterSpec("mpf-tr", "tr"))
ARM_FILTERS = ("cpf", "mpf-ball")
ROBUST_DUAL_SHARE = "evidence"
"""The robust MPFs' split between their sets (Augmented MCL's idea, after Thrun, Burgard and
Fox, Table 8.3: duals in proportion to the share of the reading the prior fails to
explain; :class:`estimation.particles.filters.ManifoldParticleFilter`). After a stretch of
unusable or contradicting readings the belief may have collapsed into a wrong mode; with
the thesis' fixed split the duals are weighed by that collapsed belief's kernel density
and stay beside it, while a reading the collapsed belief cannot explain gives the duals
more of the posterior here. Measured on the hand's MPF-AM (3 pushes, 6 faults): 5 faults
unrecovered with the fixed split, 2 with this one."""
TOLERANCE = {"hand": 0.01, "arm": 0.1, "smoother": 0.005}
"""tol of the recovery rule per family (m, rad, m)."""


@dataclass(frozen=True)
class FaultOutcome:
    """One injected fault.

    Attributes:
        estimator: e.g. ``hand/mpf-am``, ``arm/cpf``, ``smoother``.
        fault: its name; trial: the experiment it was injected into.
        robust: the robust variant: the outlier gate :data:`OUTLIER_GATE` and, for an
            MPF, the split :data:`ROBUST_DUAL_SHARE`.
        finite: every estimate of the faulty run was finite.
        reported: the estimator reported rejecting the input at every step of the fault
            (None for faults without a non-finite input to reject).
        surprised: some reading of the fault had evidence below :data:`SURPRISE` (None for
            the smoother): a reading the belief did not expect, which a caller can flag;
            a stuck sensor or a burst of plausible readings need not be one.
        error_during, error_after: mean error of the faulty run during the fault and over
            the last quarter of the run (m or rad).
        clean_after, clean_after_worst: the median and the largest over the clean draws
            of the last-quarter error (m or rad).
        recovered: finite and error_after within the recovery rule.
        clean_rank: the share of the clean draws whose last-quarter error this run's
            exceeds (ties count half; 1 for a non-finite run): uniform on
            ``{0, 1/D, ..., 1}`` (D = :data:`CLEAN_DRAWS`, mean 0.5) when the run is one
            more clean draw, so its mean over many runs is the test of
            :func:`lasting_harm`. None for the smoother, which draws nothing.
    """

    estimator: str
    fault: str
    trial: int
    robust: bool
    finite: bool
    reported: bool | None
    surprised: bool | None
    error_during: float
    error_after: float
    clean_after: float
    clean_after_worst: float
    recovered: bool
    clean_rank: float | None


def recovery_bound(clean: float, tol: float, worst: float = 0.0) -> float:
    """The largest last-quarter error the recovery rule passes (m or rad):
    ``max(RECOVERY_FACTOR x clean, clean + tol, worst)`` for the clean draws' median
    ``clean`` and largest ``worst``."""
    return max(RECOVERY_FACTOR * clean, clean + tol, worst)


def _recovered(finite: bool, after: float, clean: float, tol: float,
               worst: float = 0.0) -> bool:
    return bool(finite and np.isfinite(after) and after <= recovery_bound(clean, tol, worst))


def joint_motion(motions: np.ndarray) -> np.ndarray:
    """The arm's commanded motion over consecutive updates: (k, dof) rad steps summed."""
    return np.sum(motions, axis=0)


def hand_motion(motions: np.ndarray) -> np.ndarray:
    """The palm's motion over consecutive updates: (k, 3) hand-frame motions (m, m, rad),
    each in the frame the one before left the palm in, composed in order."""
    total = np.zeros(3)
    for motion in motions:
        total = compose(total, motion)
    return total


def inject(actions: np.ndarray, readings: np.ndarray, fault: str, start: int,
           carry=joint_motion) -> tuple[np.ndarray, list[np.ndarray], slice]:
    """The inputs with ``fault`` from update ``start`` on.

    Args:
        actions: (T, a) commanded motion per update. readings: (T, S) bool.
        carry: for ``nan-action``, ``(k, a) motions -> (a,)`` their sum as one motion
            (:func:`joint_motion`, :func:`hand_motion`): the update after the stretch
            moves the belief by the whole motion since the last finite pose.

    Returns:
        actions (T, a) float, readings (T entries, float where NaN was injected, else bool)
        and the fault's updates.
    """
    length = 2 * FAULT_STEPS if fault == "contradicting" else FAULT_STEPS
    window = slice(start, min(start + length, len(actions)))
    actions = np.array(actions, dtype=float)
    out = [np.array(r, dtype=bool) for r in readings]
    if fault == "nan-action" and window.stop < len(actions):
        actions[window.stop] = carry(actions[window.start:window.stop + 1])
    for t in range(window.start, window.stop):
        if fault == "nan-action":
            actions[t] = np.nan
        elif fault == "nan-reading":
            out[t] = np.full(len(out[t]), np.nan)
        elif fault == "all-sensors-on":
            out[t] = np.ones(len(out[t]), dtype=bool)
        elif fault == "stuck-on":
            out[t] = out[t].copy()
            out[t][0] = True
        elif fault == "stuck-off":
            out[t] = np.zeros(len(out[t]), dtype=bool)
        elif fault == "contradicting":
            out[t] = np.full(len(out[t]), (t - window.start) % 2 == 0)
        else:
            raise ValueError(f"unknown fault {fault!r}; choose from {FILTER_FAULTS}")
    return actions, out, window


def _filter_run(filt, belief: ParticleBelief, actions, readings, error, rng):
    """(T,) errors after each update, and per update the input it rejected and whether
    its reading was a surprise (evidence below :data:`SURPRISE`)."""
    errors, flags = [], []
    for t, (action, reading) in enumerate(zip(actions, readings, strict=True)):
        belief, diag = filt.update(belief, action, reading, rng=rng)
        finite = np.all(np.isfinite(belief.states)) and np.all(np.isfinite(belief.log_weights))
        errors.append(error(belief, t) if finite else np.nan)
        flags.append((diag.rejected, diag.log_evidence < np.log(SURPRISE)))
    return np.array(errors), flags


def _last_quarter(errors: np.ndarray) -> float:
    return float(np.mean(errors[len(errors) - len(errors) // 4:]))


def _outcome(estimator, fault, trial, cleans: list[np.ndarray], faulty, window, flags, tol,
             robust: bool = False) -> FaultOutcome:
    """``cleans``: the clean runs' errors (T,) each."""
    finite = bool(np.all(np.isfinite(faulty)))
    steps = range(window.start, window.stop)
    reported = all(flags[t][0] == REJECTED[fault] for t in steps) if fault in REJECTED \
        else None
    surprised = any(flags[t][1] for t in steps) if flags else None
    after = _last_quarter(faulty)
    clean_afters = [_last_quarter(c) for c in cleans]
    median, worst = float(np.median(clean_afters)), max(clean_afters)
    rank = clean_rank(after if finite else np.inf, clean_afters) if len(cleans) > 1 else None
    return FaultOutcome(estimator, fault, trial, robust, finite, reported, surprised,
                        float(np.mean(faulty[window])), after, median, worst,
                        _recovered(finite, after, median, tol, worst), rank)


def clean_rank(after: float, clean_afters: list[float]) -> float:
    """The share of ``clean_afters`` that ``after`` exceeds, ties counting half (a NaN or
    infinite ``after`` exceeds them all)."""
    clean = np.asarray(clean_afters, dtype=float)
    if not np.isfinite(after):
        return 1.0
    return float((np.sum(after > clean) + 0.5 * np.sum(after == clean)) / len(clean))


def _filter_outcomes(label: str, make, actions: np.ndarray, readings: np.ndarray,
                     start: int, error, trial: int, tol: float,
                     carry=joint_motion) -> list[FaultOutcome]:
    """Every fault of :data:`FILTER_FAULTS` from update ``start``, and the sham, for the
    filter ``make`` builds, as the thesis has it and robust (:data:`ROBUST_DUAL_SHARE` and
    the outlier gate), each
    against its own clean runs.

    Args:
        make: ``(robust: bool, draw: int) -> (filter, belief, rng)``, the same seed every
            call with the same draw: draws ``0 .. CLEAN_DRAWS - 1`` are the clean runs,
            ``CLEAN_DRAWS`` the sham's and ``CLEAN_DRAWS + 1 + k`` the run with the
            ``k``-th fault.
        actions: (T, a). readings: (T, S) bool. error: ``(belief, t) -> float``.
        carry: how motions add up (:func:`inject`).
    """
    outcomes = []
    sham_window = slice(start, min(start + FAULT_STEPS, len(actions)))
    for robust in (False, True):
        runs = []
        for draw in range(CLEAN_DRAWS + 1):  # the clean draws, then the sham
            filt, belief, rng = make(robust, draw)
            runs.append(_filter_run(filt, belief, actions, list(readings), error, rng))
        cleans = [errors for errors, _ in runs[:CLEAN_DRAWS]]
        sham_errors, sham_flags = runs[CLEAN_DRAWS]
        outcomes.append(_outcome(label, SHAM, trial, cleans, sham_errors, sham_window,
                                 sham_flags, tol, robust))
        for k, fault in enumerate(FILTER_FAULTS):
            filt, belief, rng = make(robust, CLEAN_DRAWS + 1 + k)
            a, r, window = inject(actions, readings, fault, start, carry)
            errors, flags = _filter_run(filt, belief, a, r, error, rng)
            outcomes.append(_outcome(label, fault, trial, cleans, errors, window, flags, tol,
                                     robust))
    return outcomes


def hand_trials(trials: int, *, seed: int = 0) -> list[int]:
    """The first ``trials`` pushes of the MPF study's default settings that touch early
    enough for a fault after the first contact to leave a quarter of the push after it."""
    settings = TrialSettings()
    world = _hand_world()
    chosen, trial = [], 0
    while len(chosen) < trials:
        touching = world.in_contact(simulate_truth(settings, seed, trial).true_states)
        first = int(np.argmax(touching))
        if touching.any() and first + 2 * FAULT_STEPS + 2 < 0.75 * len(touching):
            chosen.append(trial)
        trial += 1
    return chosen


@lru_cache(maxsize=1)
def _hand_world() -> PlanarWorld:
    settings = TrialSettings()
    return PlanarWorld.load(settings.object, settings.sensors)


def hand_filter_faults(trial: int, spec: FilterSpec, f: int, *, seed: int = 0
                       ) -> list[FaultOutcome]:
    """Every fault of :data:`FILTER_FAULTS` and the sham in push ``trial`` of the MPF
    study's default settings for the hand filter ``spec`` (the ``f``-th of its family,
    which picks its random stream)."""
    settings = TrialSettings()
    world = _hand_world()
    truth = simulate_truth(settings, seed, trial)
    first = int(np.argmax(world.in_contact(truth.true_states)))
    actions = np.repeat(truth.action[None], len(truth.true_states), axis=0)

    def error(belief, t):
        return belief.rmse(truth.true_states[t])[0]

    def make(robust, draw):
        rng = np.random.default_rng([seed, trial, 1, f] + [draw] * (draw > 0))
        filt = build_hand_filter(world, settings, spec, truth.mean, truth.std, truth.action,
                                 seed, rng, outlier_log_evidence=OUTLIER_GATE if robust else None,
                                 dual_share=ROBUST_DUAL_SHARE if robust else "fixed")
        belief = ParticleBelief.uniform(world.sample_gaussian(
            truth.mean, truth.std, settings.particles, rng=rng))
        return filt, belief, rng

    return _filter_outcomes(f"hand/{spec.label}", make, actions, truth.observations,
                            first + 2, error, trial, TOLERANCE["hand"], hand_motion)


def hand_faults(trials: int, *, seed: int = 0, filters: tuple[FilterSpec, ...] = HAND_FILTERS,
                progress: bool = True) -> list[FaultOutcome]:
    """Every fault of :data:`FILTER_FAULTS` in the first ``trials`` pushes with contact of
    the MPF study's default settings (:func:`hand_trials`), for each of ``filters``, in
    this process."""
    jobs = [(trial, spec, f) for trial in hand_trials(trials, seed=seed)
            for f, spec in enumerate(filters)]
    return [outcome for trial, spec, f in tqdm(jobs, desc="hand filters",
                                               disable=not progress, leave=False)
            for outcome in hand_filter_faults(trial, spec, f, seed=seed)]


@lru_cache(maxsize=1)
def _arm_setup():
    settings = ConfigestSettings(arms=("3dof",), trials=2)
    return settings, arm_world("3dof", settings.process_noise_radius_rad)


def arm_filter_faults(trial: int, kind: str, f: int, *, seed: int = 0) -> list[FaultOutcome]:
    """Every fault of :data:`FILTER_FAULTS` and the sham in experiment ``trial`` of the
    3-DOF arm for the configuration filter ``kind`` (the ``f``-th of
    :data:`ARM_FILTERS`) of the configuration study (n = 250)."""
    settings, world = _arm_setup()
    trajectory = world.simulate(rng=np.random.default_rng((seed, 31, trial)))
    start = int(np.argmax(world.true_contacts(trajectory.q_true[1:]).any(axis=1))) + 2

    def error(belief, t):
        return joint_rmse(world, belief, trajectory.q_true[t + 1])

    def make(robust, draw):
        rng = np.random.default_rng([seed, 31, trial, 1 + f] + [draw] * (draw > 0))
        filt, n, _ = build_filter(
            world, kind, replace(settings, dual_share=ROBUST_DUAL_SHARE) if robust else settings,
            outlier_log_evidence=OUTLIER_GATE if robust else None)
        belief = ParticleBelief.uniform(world.initial_belief_states(
            trajectory.encoders[0], n, rng=rng), world.angular)
        return filt, belief, rng

    return _filter_outcomes(f"arm/{kind}", make, trajectory.commanded,
                            trajectory.contacts[1:], start, error, trial, TOLERANCE["arm"])


def inject_smoother(steps: PushingSteps, fault: str, start: int) -> tuple[PushingSteps, slice]:
    """``steps`` with ``fault`` for :data:`SMOOTHER_FAULT_S` from step ``start``."""
    if fault not in SMOOTHER_FAULTS:
        raise ValueError(f"unknown fault {fault!r}; choose from {SMOOTHER_FAULTS}")
    dt = float(np.median(np.diff(steps.t)))
    window = slice(start, min(start + int(round(SMOOTHER_FAULT_S / dt)), len(steps)))
    forces, vision = steps.forces.copy(), steps.vision.copy()
    vision_ok, contact = steps.vision_ok.copy(), steps.contact.copy()
    if fault in ("nan-force", "blind"):
        forces[window] = np.nan
    if fault in ("nan-camera", "blind"):
        vision[window] = np.nan
    if fault == "teleported-camera":
        vision[window] += np.array([0.3, 0.3, 1.0])
    if fault == "dropped-frames":
        vision_ok[window] = False
    if fault == "stuck-contact":  # the force sensors freeze on their last reading
        contact[window] = True
        forces[window] = forces[window.start - 1]
    return replace(steps, forces=forces, vision=vision, vision_ok=vision_ok,
                   contact=contact), window


def smoother_faults(steps: PushingSteps, polygon: np.ndarray, *, progress: bool = True
                    ) -> list[FaultOutcome]:
    """Every fault of :data:`SMOOTHER_FAULTS` in one push (``steps``, with ground truth),
    from the first step where a rod touches and the camera sees (the camera is occluded
    for much of a push: a camera fault there would change nothing), for the smoother of
    :func:`recommended_settings`."""
    noise, _, _ = identify_from_runs([steps], polygon)

    def run(s: PushingSteps) -> tuple[np.ndarray, int]:
        smoother = VisuoTactileSmoother(polygon, noise, recommended_settings(),
                                        rod_radius_m=s.rod_radius_m)
        estimates = smoother.run(s)
        return np.linalg.norm(estimates[:, :2] - s.truth[:, :2], axis=1), \
            smoother.rejected_inputs

    clean, _ = run(steps)
    begun = np.isfinite(clean)
    clean = clean[begun]
    outcomes = []
    start = int(np.argmax(steps.contact.any(axis=1) & steps.vision_ok))
    for fault in tqdm(SMOOTHER_FAULTS, desc="smoother", disable=not progress, leave=False):
        faulty_steps, window = inject_smoother(steps, fault, start)
        errors, rejected = run(faulty_steps)
        errors = errors[begun]
        shift = int(np.argmax(begun))
        window = slice(window.start - shift, window.stop - shift)
        reported = rejected > 0 if fault.startswith("nan-") or fault == "blind" else None
        # a NaN left in an estimate would make errors NaN: finite is checked on them
        outcome = _outcome("smoother", fault, 0, [clean], errors, window, [], TOLERANCE[
            "smoother"])  # the smoother draws nothing: one clean run is every draw
        outcomes.append(replace(outcome, reported=reported))
    return outcomes


def simulated_push(seed: int = 0) -> tuple[PushingSteps, np.ndarray]:
    """A short simulated push of rect1 on plywood (the first three strokes of the
    standard procedure) and the object's outline."""
    from diagrams.pusher.simulation import simulate_push
    from models.pusher.procedure import standard_procedure
    from models.pusher.rig import PusherSliderRig

    spec = ObjectSpec.load("rect1")
    run = simulate_push(PusherSliderRig.load(), spec, standard_procedure()[:3], seed=seed,
                        object_name="rect1")
    return PushingSteps.from_log(run.log), spec.footprint()


def fault_job(family: str, trial: int, index: int, seed: int) -> list[FaultOutcome]:
    """One job of the fault bench (:func:`measure_faults`): the ``index``-th filter of
    ``family`` (``hand``: :data:`HAND_FILTERS`, ``arm``: :data:`ARM_FILTERS`) in experiment
    ``trial``, or the smoother (``family="smoother"``) on :func:`simulated_push`. Each
    worker builds its worlds from these keys."""
    if family == "hand":
        return hand_filter_faults(trial, HAND_FILTERS[index], index, seed=seed)
    if family == "arm":
        return arm_filter_faults(trial, ARM_FILTERS[index], index, seed=seed)
    if family == "smoother":
        steps, polygon = simulated_push(seed)
        return smoother_faults(steps, polygon, progress=False)
    raise ValueError(f"unknown fault family {family!r}")


def unrecovered_rates(outcomes: list[FaultOutcome]) -> dict:
    """The share of filter runs the recovery rule fails, faulty against sham, per variant.

    A sham is one more clean draw, so its failure rate is the rule's false-alarm rate; a
    fault does lasting harm in the measured sense only where its runs fail clearly more
    often than the shams do. Returns ``{"thesis"|"robust": {"faults"|"shams":
    {"failed", "runs", "rate", "ci95": [lo, hi]}}}`` (Wilson 95 %) over the particle
    filters' runs (the smoother has no sham); a variant or kind without runs is left out.
    """
    out = {}
    for robust, variant in ((False, "thesis"), (True, "robust")):
        runs = [o for o in outcomes if o.robust == robust and o.estimator != "smoother"]
        kinds = {"faults": [o for o in runs if o.fault != SHAM],
                 "shams": [o for o in runs if o.fault == SHAM]}
        entry = {}
        for kind, chosen in kinds.items():
            if chosen:
                failed = sum(not o.recovered for o in chosen)
                entry[kind] = {"failed": failed, "runs": len(chosen),
                               "rate": failed / len(chosen),
                               "ci95": list(wilson_interval(failed, len(chosen)))}
        if entry:
            out[variant] = entry
    return out


def lasting_harm(outcomes: list[FaultOutcome], draws: int = CLEAN_DRAWS) -> dict:
    """Whether faults leave the particle filters worse than a clean draw, over many runs.

    The recovery rule judges one run against :data:`CLEAN_DRAWS` others and fails about
    one clean draw in ``CLEAN_DRAWS + 1``. Pooled, the runs' :attr:`FaultOutcome.clean_rank`
    is a sharper test: with no lasting harm a faulty run is one more clean draw, its rank
    uniform on ``{0, 1/D, ..., 1}`` and the mean rank 0.5, while a fault that leaves the
    filter in a wrong mode pushes its runs above the clean draws. Each run is ranked only
    against the clean draws of its own experiment and filter, so the test is the
    stratified Mann-Whitney test (van Elteren's design;
    :func:`experiments.statistics.rank_sum_p_value`). Per
    variant (``thesis``, ``robust``), grouped ``faults`` (every faulty run, as the
    group ``all``), ``by_estimator``, ``by_fault`` (each fault over every filter), and the
    shams, ``shams`` (as ``all``) and ``shams_by_estimator`` (the test's calibration:
    they are clean draws), each group ``{"runs", "mean_rank", "ci95" (half-width,
    normal, clustered by experiment: the runs of one experiment share its clean draws),
    "p_one_sided", "harmed", "harmed_share_upper95"}``; ``harmed`` is Holm's test at 5 %
    over every group of the grouping (both variants), so a grouping's false alarms stay
    below 5 % in all; ``harmed_share_upper95`` bounds the share of the group's runs that a
    fault left above all their clean draws
    (:func:`experiments.statistics.harmed_share_upper`): what the test, when it finds no
    harm, still cannot rule out."""
    runs = [o for o in outcomes if o.clean_rank is not None]
    groupings = {
        "faults": lambda o: None if o.fault == SHAM else "all",
        "by_estimator": lambda o: None if o.fault == SHAM else o.estimator,
        "by_fault": lambda o: None if o.fault == SHAM else o.fault,
        "shams": lambda o: "all" if o.fault == SHAM else None,
        "shams_by_estimator": lambda o: o.estimator if o.fault == SHAM else None,
    }
    out = {"draws": draws}
    for name, key in groupings.items():
        groups: dict = {}
        for o in runs:
            if key(o) is not None:
                group = groups.setdefault(("robust" if o.robust else "thesis", key(o)), {})
                group.setdefault((o.estimator, o.trial), []).append(o.clean_rank)
        cells = {}
        for k, by_experiment in sorted(groups.items()):
            strata = [np.array(r) for r in by_experiment.values()]
            ranks = np.concatenate(strata)
            cells[k] = {"runs": len(ranks), "mean_rank": float(np.mean(ranks)),
                        "ci95": clustered_half_width(strata),
                        "p_one_sided": rank_sum_p_value(strata, draws),
                        "harmed_share_upper95": harmed_share_upper(strata, draws)}
        rejected = holm({k: c["p_one_sided"] for k, c in cells.items()})
        entry: dict = {}
        for (variant, group), cell in cells.items():
            entry.setdefault(variant, {})[group] = dict(cell, harmed=rejected[(variant, group)])
        out[name] = entry
    return out


def measure_faults(*, trials: int = 3, seed: int = 0, progress: bool = True,
                   backend: Backend = Backend("serial")) -> dict:
    """Every estimator under every fault: ``faults_injected`` (each fault once),
    ``faults_recovered`` (the robust filters, the smoother as it is),
    ``faults_recovered_plain`` (the filters as the thesis has them),
    ``sham_runs`` and ``sham_recovered`` (the control, both filter variants: the rule's
    pass rate without a fault), ``unrecovered_rates`` (:func:`unrecovered_rates`: the
    faults' failure rate beside the shams'), ``lasting_harm`` (:func:`lasting_harm`: the
    pooled test against the clean draws), ``faults_non_finite``
    (runs with a NaN or infinite estimate, either way), ``faults_reported`` of
    ``faults_non_finite_input`` (the faults feeding NaN or infinite inputs, which the
    estimator must report rejecting) and each outcome. One job per (family, experiment,
    filter) and one for the smoother, on ``backend`` (:func:`experiments.runner.map_trials`:
    the outcomes do not depend on it)."""
    jobs = [Job(f"hand/{trial}/{spec.label}", ("hand", trial, f, seed))
            for trial in hand_trials(trials, seed=seed) for f, spec in enumerate(HAND_FILTERS)]
    jobs += [Job(f"arm/{trial}/{kind}", ("arm", trial, f, seed))
             for trial in range(trials) for f, kind in enumerate(ARM_FILTERS)]
    jobs.append(Job("smoother", ("smoother", 0, 0, seed)))
    outcomes = [outcome for result in map_trials(fault_job, jobs, backend=backend,
                                                 desc="faults", progress=progress)
                for outcome in result]
    shams = [o for o in outcomes if o.fault == SHAM]
    faulty = [o for o in outcomes if o.fault != SHAM]
    # each fault once: the smoother's outcome and the robust filters'
    counted = [o for o in faulty if o.robust or o.estimator == "smoother"]
    plain = [o for o in faulty if not o.robust]
    detectable = [o for o in counted if o.reported is not None]
    return {
        "sham_runs": len(shams),
        "sham_recovered": sum(o.recovered for o in shams),
        "faults_injected": len(counted),
        "faults_recovered": sum(o.recovered for o in counted),
        "faults_recovered_plain": sum(o.recovered for o in plain),
        "faults_non_finite": sum(not o.finite for o in outcomes),
        "faults_non_finite_input": len(detectable),
        "faults_reported": sum(bool(o.reported) for o in detectable),
        "unrecovered_rates": unrecovered_rates(outcomes),
        "lasting_harm": lasting_harm(outcomes),
        "fault_outcomes": [asdict(o) for o in outcomes],
    }
