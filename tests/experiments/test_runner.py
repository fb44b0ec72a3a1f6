"""The trial runner: backends agree, results survive a kill, a foreign trials file is
refused."""

import json
import operator
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from cmanip.cli import main
from experiments.configest_study import ConfigestSettings, TrialResult
from experiments.runner import (
    TRIALS_FILE,
    Backend,
    Job,
    TrialStore,
    decode,
    encode,
    map_trials,
)


def test_encoding_round_trips_results_exactly():
    result = TrialResult(
        rmse_rad={"cpf": np.array([0.1, 1 / 3, np.nan]), "mpf-ball": np.arange(3.0)},
        update_ms={"cpf": 1.25}, projection={"mpf-ball": (10, 2)}, contact_steps=4)
    back = decode(json.loads(json.dumps(encode(result))))
    assert isinstance(back, TrialResult) and back.projection == {"mpf-ball": (10, 2)}
    np.testing.assert_array_equal(back.rmse_rad["cpf"], result.rmse_rad["cpf"])
    flags = decode(encode(np.array([[True, False]])))
    assert flags.dtype == bool and flags.shape == (1, 2)
    with pytest.raises(ValueError, match="this project's classes"):
        decode({"__dataclass__": "subprocess.Popen", "fields": {}})


def test_the_store_drops_a_line_cut_short_and_refuses_other_settings(tmp_path):
    store = TrialStore(tmp_path, "demo", {"seed": 1}, resume=False)
    store.append("a", encode(1.5))
    with open(tmp_path / TRIALS_FILE, "a") as f:
        f.write('{"key": "b", "resu')  # killed mid-write
    again = TrialStore(tmp_path, "demo", {"seed": 1}, resume=True)
    assert again.done == {"a": 1.5}
    again.append("b", encode(2.5))
    assert TrialStore(tmp_path, "demo", {"seed": 1}, resume=True).done == {"a": 1.5, "b": 2.5}
    with pytest.raises(ValueError, match=r"other settings \(seed: stored 1, now 2\)"):
        TrialStore(tmp_path, "demo", {"seed": 2}, resume=True)
    with pytest.raises(ValueError, match="written by study 'demo'"):
        TrialStore(tmp_path, "other", {"seed": 1}, resume=True)
    assert TrialStore(tmp_path, "demo", {"seed": 2}, resume=False).done == {}


def test_only_missing_trials_run_and_results_come_back_in_job_order(tmp_path):
    jobs = [Job(f"j{i}", (float(i), 2.0)) for i in range(5)]
    store = TrialStore(tmp_path, "pow", {}, resume=False)
    store.append("j3", encode(-1.0))  # a stored result is used, not recomputed
    out = map_trials(operator.pow, jobs, backend=Backend("serial"), store=store,
                     progress=False)
    assert out == [0.0, 1.0, 4.0, -1.0, 16.0]
    with pytest.raises(ValueError, match="unique"):
        map_trials(operator.pow, jobs + jobs[:1], backend=Backend("serial"), progress=False)
    with pytest.raises(ValueError, match="backend must be one of"):
        Backend("threads")


def _wait_for_trials(child: subprocess.Popen, trials, count: int) -> None:
    """Until ``trials`` holds ``count`` finished trials (after its header line), the child
    ends, or five minutes pass."""
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and child.poll() is None:
        if trials.exists() and trials.read_text().count("\n") >= 1 + count:
            return
        time.sleep(0.05)


MPF = ["experiment", "mpf", "--part", "compare", "--push-distance", "0.2", "--no-progress"]
"""A small MPF study: about 10 s to start (the analytic manifold, the figures), then a
fifth of a second per trial."""


def test_serial_processes_and_ray_give_the_same_study(tmp_path):
    for backend in ("serial", "processes", "ray"):
        assert main(MPF + ["--trials", "4", "--backend", backend, "--workers", "2", "--out",
                           str(tmp_path / backend)]) == 0
    serial = (tmp_path / "serial" / "summary.json").read_text()
    assert (tmp_path / "processes" / "summary.json").read_text() == serial
    assert (tmp_path / "ray" / "summary.json").read_text() == serial


def test_a_study_killed_part_way_and_resumed_gives_the_uninterrupted_summary(tmp_path):
    args = MPF + ["--trials", "60", "--backend", "serial"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    assert main(args + ["--out", str(whole)]) == 0
    child = subprocess.Popen([sys.executable, "-m", "cmanip.cli", *args, "--out",
                              str(killed)], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    trials = killed / TRIALS_FILE
    _wait_for_trials(child, trials, 5)
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    kept = trials.read_text().count("\n") - 1
    assert 5 <= kept < 60 and not (killed / "summary.json").exists()
    with open(trials, "a") as f:
        f.write('{"key": "compare/')  # as if killed mid-line
    assert main(args + ["--out", str(killed), "--resume"]) == 0
    assert ((killed / "summary.json").read_text()
            == (whole / "summary.json").read_text())
    # a trials file from other settings is refused, not mixed in
    assert main(args + ["--out", str(killed), "--resume", "--seed", "5"]) == 2


@pytest.mark.parametrize("started_in_background", [False, True])
def test_ctrl_c_stops_the_workers_keeps_the_finished_trials_and_says_how_to_resume(
        tmp_path, started_in_background):
    """Also when started with SIGINT ignored, as a shell script's ``cmanip ... &``."""
    out = tmp_path / "mpf"
    ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) \
        if started_in_background else None
    child = subprocess.Popen(
        [sys.executable, "-m", "cmanip.cli", *MPF, "--trials", "200", "--workers", "2",
         "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=ignore)
    trials = out / TRIALS_FILE
    _wait_for_trials(child, trials, 1)
    child.send_signal(signal.SIGINT)
    _, err = child.communicate(timeout=120)
    assert child.returncode == 130
    assert "interrupted" in err and "--resume" in err and "Traceback" not in err
    assert 1 <= trials.read_text().count("\n") - 1 < 200


def test_a_trials_file_of_other_settings_is_a_clear_error(tmp_path, capsys):
    settings = ConfigestSettings(arms=("2dof",), trials=2)
    TrialStore(tmp_path, "configest", {"seed": 9}, resume=False)
    assert main(["experiment", "configest", "--arm", "2dof", "--trials",
                 str(settings.trials), "--out", str(tmp_path), "--resume"]) == 2
    err = capsys.readouterr().err
    assert TRIALS_FILE in err and "other settings" in err and "seed" in err



def test_runner_options_out_of_place_are_clear_errors(tmp_path, capsys):
    assert main(MPF + ["--trials", "2", "--address", "auto", "--out", str(tmp_path)]) == 2
    assert "--address is for the ray backend" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(MPF + ["--trials", "2", "--workers", "0", "--out", str(tmp_path)])
    assert exit_.value.code == 2
    assert "must be >= 1" in capsys.readouterr().err


def test_a_local_ray_start_that_times_out_is_tried_again():
    from experiments.runner import LOCAL_RAY_ATTEMPTS, _start_local_ray

    class SlowRay:  # times out starting, as a loaded machine can make Ray's raylet do
        def __init__(self, failures):
            self.failures, self.inits, self.shutdowns = failures, 0, 0

        def init(self, **kwargs):
            self.inits += 1
            assert kwargs["_node_ip_address"] == "127.0.0.1" and kwargs["num_cpus"] == 2
            if self.inits <= self.failures:
                raise Exception("The current node timed out during startup.")

        def shutdown(self):
            self.shutdowns += 1

    ray = SlowRay(failures=LOCAL_RAY_ATTEMPTS - 1)
    _start_local_ray(ray, 2)
    assert ray.inits == LOCAL_RAY_ATTEMPTS and ray.shutdowns == LOCAL_RAY_ATTEMPTS - 1
    with pytest.raises(Exception, match="timed out"):
        _start_local_ray(SlowRay(failures=LOCAL_RAY_ATTEMPTS), 2)
