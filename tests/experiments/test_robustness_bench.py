"""The fault bench and the load bench on small settings: faults are injected where they
say, a CPF under every fault stays finite and reports what it can, and the budget and
memory statistics are what they claim."""

import time

import numpy as np
import pytest

from experiments.fault_bench import (
    FILTER_FAULTS,
    HAND_FILTERS,
    SHAM,
    FaultOutcome,
    clean_rank,
    fault_job,
    hand_faults,
    hand_motion,
    inject,
    inject_smoother,
    joint_motion,
    lasting_harm,
    unrecovered_rates,
)
from experiments.load_bench import (
    BusyCore,
    _budget_report,
    growth_mb_per_1000,
    meshcat_sessions,
)
from experiments.mpf_study import FilterSpec
from experiments.runner import Backend, Job, map_trials


def test_inject_puts_each_fault_in_its_window():
    actions = np.ones((30, 3))
    readings = np.zeros((30, 4), dtype=bool)
    a, r, window = inject(actions, readings, "nan-action", 5)
    assert window == slice(5, 15) and np.isnan(a[5:15]).all() and np.isfinite(a[15:]).all()
    assert np.allclose(a[15], 11) and np.allclose(a[16:], 1)  # the gap's motion carried over
    _, r, _ = inject(actions, readings, "nan-reading", 5)
    assert np.isnan(r[5]).all() and r[15].dtype == bool
    _, r, window = inject(actions, readings, "contradicting", 5)
    assert window == slice(5, 25) and r[5].all() and not r[6].any()
    _, r, _ = inject(actions, readings, "stuck-on", 5)
    assert r[7][0] and not r[7][1:].any() and not r[4].any()
    with pytest.raises(ValueError, match="unknown fault"):
        inject(actions, readings, "gremlins", 5)


def test_hand_motion_composes_palm_motions_in_order():
    quarter_turn_then_forward = np.array([[0.0, 0.0, np.pi / 2], [0.1, 0.0, 0.0]])
    assert np.allclose(hand_motion(quarter_turn_then_forward), [0.0, 0.1, np.pi / 2])
    assert np.allclose(hand_motion(quarter_turn_then_forward[::-1]), [0.1, 0.0, np.pi / 2])
    assert np.allclose(joint_motion(np.ones((4, 7))), 4)


def test_inject_smoother_freezes_and_drops(synthetic_push_log):
    from estimation.pushing.inputs import PushingSteps

    steps = PushingSteps.from_log(synthetic_push_log)
    dropped, window = inject_smoother(steps, "dropped-frames", 100)
    assert window.stop - window.start == 100  # 1 s at 100 Hz
    assert not dropped.vision_ok[window].any() and dropped.vision_ok.sum() > 0
    stuck, _ = inject_smoother(steps, "stuck-contact", 100)
    assert stuck.contact[window].all()
    np.testing.assert_array_equal(stuck.forces[120], steps.forces[99])
    blind, _ = inject_smoother(steps, "blind", 100)
    assert np.isnan(blind.forces[window]).all() and np.isnan(blind.vision[window]).all()
    assert np.isfinite(blind.rods[window]).all()  # the arm still knows where the rods are
    with pytest.raises(ValueError, match="unknown fault"):
        inject_smoother(steps, "gremlins", 100)


def test_a_fault_job_gives_the_same_outcomes_in_a_worker_process():
    serial = fault_job("hand", 0, 0, 0)  # the hand CPF in the first push
    pooled = map_trials(fault_job, [Job("hand/0/cpf", ("hand", 0, 0, 0))],
                        backend=Backend("processes", 1), progress=False)[0]
    assert pooled == serial and len(serial) == 2 * (len(FILTER_FAULTS) + 1)


def test_the_fault_bench_runs_one_job_per_filter_and_experiment(monkeypatch):
    import experiments.fault_bench as bench

    seen = []

    def job(family, trial, index, seed):
        seen.append((family, trial, index))
        return [FaultOutcome(family, "nan-action", trial, True, True, True, False, 0.0, 0.0,
                             0.0, 0.0, True, None)]

    monkeypatch.setattr(bench, "fault_job", job)
    report = bench.measure_faults(trials=2, progress=False, backend=Backend("serial"))
    hands = [s for s in seen if s[0] == "hand"]
    assert len(hands) == 2 * len(HAND_FILTERS) and ("smoother", 0, 0) in seen
    assert len([s for s in seen if s[0] == "arm"]) == 4
    assert report["faults_injected"] == len(seen) == report["faults_recovered"]
    with pytest.raises(ValueError, match="unknown fault family"):
        fault_job("gremlins", 0, 0, 0)


def test_unrecovered_rates_set_the_faults_failures_beside_the_shams():
    def outcome(estimator, fault, robust, recovered):
        return FaultOutcome(estimator, fault, 0, robust, True, None, False, 0.0, 0.0, 0.0,
                            0.0, recovered, None)

    outcomes = ([outcome("hand/cpf", "stuck-on", True, i < 3) for i in range(4)]
                + [outcome("hand/cpf", SHAM, True, True), outcome("hand/cpf", SHAM, True, False)]
                + [outcome("hand/cpf", "stuck-on", False, True)]
                + [outcome("smoother", "blind", False, False)])
    rates = unrecovered_rates(outcomes)
    robust = rates["robust"]
    assert (robust["faults"]["failed"], robust["faults"]["runs"]) == (1, 4)
    assert robust["faults"]["rate"] == pytest.approx(0.25)
    assert robust["shams"]["rate"] == pytest.approx(0.5)
    lo, hi = robust["faults"]["ci95"]
    assert 0.0 < lo < 0.25 < hi < 1.0
    # the smoother has no sham and is left out; a variant without shams has faults only
    assert rates["thesis"] == {"faults": {"failed": 0, "runs": 1, "rate": 0.0,
                                          "ci95": [0.0, pytest.approx(0.7935, abs=1e-3)]}}


def test_a_run_is_ranked_among_its_clean_draws_ties_counting_half():
    assert clean_rank(0.5, [0.1, 0.2, 0.9, 1.0]) == 0.5
    assert clean_rank(0.2, [0.1, 0.2, 0.9, 1.0]) == pytest.approx(0.375)
    assert clean_rank(float("nan"), [0.1, 0.2]) == 1.0


def test_lasting_harm_flags_the_filter_whose_runs_end_above_their_clean_draws():
    rng = np.random.default_rng(1)

    def outcome(estimator, fault, trial, rank):
        return FaultOutcome(estimator, fault, trial, True, True, None, False, 0.0, 0.0, 0.0,
                            0.0, True, rank)

    outcomes = [outcome("hand/cpf", "stuck-on", t, r)
                for t, r in enumerate(rng.integers(0, 6, 40) / 5)]
    outcomes += [outcome("hand/mpf-am", "stuck-on", t, r)
                 for t, r in enumerate(rng.integers(3, 6, 40) / 5)]
    outcomes += [outcome("hand/mpf-am", SHAM, t, r)
                 for t, r in enumerate(rng.integers(0, 6, 10) / 5)]
    outcomes.append(outcome("smoother", "blind", 0, None))  # no clean draws to rank against
    harm = lasting_harm(outcomes)
    robust = harm["by_estimator"]["robust"]
    assert robust["hand/mpf-am"]["harmed"] and not robust["hand/cpf"]["harmed"]
    assert robust["hand/mpf-am"]["runs"] == 40 and "smoother" not in robust
    assert robust["hand/mpf-am"]["mean_rank"] > 0.7 > robust["hand/cpf"]["mean_rank"]
    assert not harm["shams"]["robust"]["all"]["harmed"]
    assert harm["by_fault"]["robust"]["stuck-on"]["runs"] == 80
    assert harm["faults"]["robust"]["all"]["runs"] == 80
    assert harm["shams_by_estimator"]["robust"]["hand/mpf-am"]["runs"] == 10
    assert "thesis" not in harm["by_estimator"]
    # the harmed filter's runs sit at 3-5 of 5: the bound cannot rule out that most were
    assert robust["hand/mpf-am"]["harmed_share_upper95"] > 0.5
    assert robust["hand/cpf"]["harmed_share_upper95"] < robust["hand/mpf-am"][
        "harmed_share_upper95"]


def test_a_cpf_under_every_fault_stays_finite_and_reports_what_it_can():
    outcomes = hand_faults(1, filters=(FilterSpec("cpf", "cpf"),), progress=False)
    shams = [o for o in outcomes if o.fault == SHAM]
    assert len(outcomes) == 2 * (len(FILTER_FAULTS) + 1)  # as in the thesis and robust
    assert len(shams) == 2 and {o.robust for o in shams} == {False, True}
    assert all(o.reported is None and np.isfinite(o.error_after) for o in shams)
    assert all(isinstance(o, FaultOutcome) and o.finite for o in outcomes)
    reported = {o.fault: o.reported for o in outcomes}
    assert reported["nan-action"] and reported["nan-reading"]
    assert reported["stuck-on"] is None and reported["all-sensors-on"] is None
    assert all(isinstance(o.surprised, bool) for o in outcomes)
    assert all(np.isfinite(o.error_after) for o in outcomes)


def test_growth_is_the_slope_after_the_warm_up():
    steps = np.arange(100, 10_001, 100)
    rss = 500.0 + 0.002 * steps  # 2 MB per 1000 steps
    rss[:5] += 50.0  # a warm-up bump, left out
    assert growth_mb_per_1000(steps, rss) == pytest.approx(2.0)


def test_budget_report_counts_overruns_and_the_allowance():
    runs = {"idle": {"wall_ms": np.array([95.0, 101.0, 130.0]),
                     "trial_ms_max": np.array([5.0, 5.0, 5.0])}}
    report = _budget_report(runs, 0.1)["idle"]
    assert report["overrun_ms_max"] == pytest.approx(30.0)
    assert report["allowed_p99_ms"] == pytest.approx(15.0)
    assert not report["within_budget"]


def test_busy_core_runs_a_process_and_stops_it():
    with BusyCore() as busy:
        time.sleep(0.2)
        assert busy._process.is_alive()
    assert not busy._process.is_alive()


def test_meshcat_sessions_count_their_clients_and_leave_nothing_open():
    report = meshcat_sessions(3, progress=False)
    assert report["clients_connected"] == 3  # the handshake is a connection Drake counts
    assert report["connections_left_open"] == 0
    assert report["after"] == report["before"]  # threads, descriptors, listening sockets


def test_the_fault_figure_puts_exactly_the_unrecovered_runs_past_the_bound(tmp_path):
    from dataclasses import asdict

    from experiments.fault_plots import bound_ratio, plot_fault_recovery

    runs = hand_faults(1, filters=(FilterSpec("cpf", "cpf"),), progress=False)
    harm = lasting_harm(runs)
    outcomes = [asdict(o) for o in runs]
    outcomes.append(dict(outcomes[0], fault="stuck-on", error_after=1.0, recovered=False))
    outcomes.append(dict(outcomes[0], fault="nan-action", finite=False, recovered=False))
    assert all((bound_ratio(o) <= 1) == o["recovered"] for o in outcomes)
    assert bound_ratio(outcomes[-1]) == float("inf")
    assert plot_fault_recovery(outcomes, harm, tmp_path / "faults.png") == "faults.png"
    assert (tmp_path / "faults.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="no fault outcomes"):
        plot_fault_recovery([], harm, tmp_path / "empty.png")
