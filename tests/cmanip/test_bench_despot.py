"""``cmanip bench despot``: a .pomdp file runs through DESPOT unchanged, the JSON holds
what the issue names, and a bad problem is a clear error (exit 2); ``cmanip bench
latdespot`` likewise refuses bad input."""

import json

from cmanip.cli import main
from planning.pomdp.benchmarks import tiger
from planning.pomdp.cassandra import write_pomdp


def test_a_pomdp_file_runs_through_the_bench(tmp_path, capsys):
    path = tmp_path / "tiger.pomdp"
    write_pomdp(tiger(), path)
    out = tmp_path / "bench.json"
    assert main(["bench", "despot", "--problem", str(path), "--seconds-per-step", "0.02",
                 "--episodes", "2", "--steps", "3", "--scenarios", "50", "--no-progress",
                 "--json", str(out)]) == 0
    report = json.loads(out.read_text())[str(path)]["0.02"]
    for key in ("discounted_return_mean", "discounted_return_ci95", "episodes",
                "decision_ms_p50", "decision_ms_p99", "budget_overrun_ms_max"):
        assert key in report
    assert report["episodes"] == 2 and report["decisions"] == 6
    assert "tiger.pomdp at 0.02 s: DESPOT" in capsys.readouterr().out


def test_a_bad_problem_is_a_clear_error(tmp_path, capsys):
    assert main(["bench", "despot", "--problem", "rocksample:7"]) == 2
    assert "rocksample:N:K" in capsys.readouterr().err
    assert main(["bench", "despot", "--problem", str(tmp_path / "none.pomdp")]) == 2
    assert "none.pomdp" in capsys.readouterr().err


def test_the_lat_despot_bench_refuses_bad_input_before_building_anything(tmp_path):
    assert main(["bench", "latdespot", "--decisions", "0"]) == 2
    assert main(["bench", "latdespot", "--scene", str(tmp_path / "none.yaml")]) == 2
