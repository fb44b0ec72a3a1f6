"""The visuo-tactile study's comparison, figures and bench, on Drake-free synthetic logs."""

import json

import numpy as np

from cmanip.cli import main
from estimation.pushing.inputs import PushingSteps
from estimation.pushing.noise import identify_from_runs
from experiments import visuotactile_plots as plots
from experiments.visuotactile_study import PAPER_TABLE_II, Method, compare, paper_methods
from models.objects import ObjectSpec

RECT1 = ObjectSpec.load("rect1").footprint()


def _noise(logs):
    return identify_from_runs([PushingSteps.from_log(log) for log in logs], RECT1)[0]


def test_compare_summarises_every_method_and_plots(synthetic_push_factory, tmp_path):
    logs = [synthetic_push_factory(seed).head(400) for seed in (11, 12)]
    noise = _noise([synthetic_push_factory(99)])
    keep = {"vision only", "EKF", "iSAM 200-step", "iSAM 200-step, contact-aware prior (ours)"}
    methods = tuple(m for m in paper_methods(200) if m.label in keep)
    results, traces = compare(methods, logs, RECT1, noise, progress=False)
    assert set(results) == {m.label for m in methods}
    for entry in results.values():
        assert entry["rmse_mm"]["mean"] > 0 and len(entry["per_trial_mm"]) == 2
    ours = results["iSAM 200-step, contact-aware prior (ours)"]
    assert ours["rmse_mm"]["mean"] < results["vision only"]["rmse_mm"]["mean"] / 2
    assert "update_ms_mean" in results["iSAM 200-step"]["timing"]
    names = plots.methods_figures(results, traces, PAPER_TABLE_II, tmp_path)
    names.append(plots.timing_figure(results, tmp_path))
    for name in names:
        assert (tmp_path / name).stat().st_size > 1000


def test_a_failed_estimate_is_reported_not_raised(synthetic_push_log):
    """Without the stationary prior and with no contact or camera, GTSAM's system is
    under-determined: the study records the failure and goes on."""
    noise = _noise([synthetic_push_log])
    from estimation.pushing.smoother import SmootherSettings

    method = Method("motion only, no prior", "isam", SmootherSettings(costs=("motion",)))
    results, _ = compare((method,), [synthetic_push_log], RECT1, noise, start_at_truth=True,
                         progress=False)
    entry = results[method.label]
    assert entry["rmse_mm"]["mean"] is None and entry["rmse_mm"]["failed_trials"] == 1
    assert entry["failures"]


def test_bench_on_a_log_writes_the_issue_keys(synthetic_push_log, tmp_path):
    path = tmp_path / "push.csv"
    synthetic_push_log.write(path)
    report_path = tmp_path / "bench.json"
    assert main(["bench", "visuotactile", "--log", str(path), "--json", str(report_path)]) == 0
    report = json.loads(report_path.read_text())
    for key in ("update_ms_mean", "update_ms_p99", "update_ms_max", "relinearize_ms_mean"):
        assert np.isfinite(report[key]) and report[key] > 0
    assert report["update_ms_max"] >= report["update_ms_p99"] >= 0


def test_simulated_logs_reuse_the_logs_directory(tmp_path, synthetic_push_log):
    """The trial runner's jobs for the push simulations read a log that is already in the
    logs directory rather than simulating it again (what makes a killed study cheap to
    restart); a half-written log never takes a log's name."""
    from experiments.runner import Backend
    from experiments.visuotactile_study import VisuotactileSettings, log_path, simulated_logs

    settings = VisuotactileSettings(trials=2)
    for i in range(2):
        synthetic_push_log.write(log_path(settings, "rect1", "plywood", i, tmp_path))
    logs = simulated_logs(settings, "rect1", "plywood", tmp_path, count=2,
                          backend=Backend("serial"), progress=False)
    assert len(logs) == 2
    np.testing.assert_allclose(logs[1].t, synthetic_push_log.t, atol=1e-6)
    assert not list(tmp_path.glob("*.part"))
