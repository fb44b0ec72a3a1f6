"""The MPF study: outputs, reproducibility, user objects, CLI errors (tiny settings)."""

import json

import numpy as np

from cmanip.cli import main
from experiments.mpf_study import FilterSpec, TrialSettings, run_part, run_trial

TINY = TrialSettings(push_distance_m=0.2, update_interval_m=0.01, particles=30,
                     dual_particles=8, am_dtheta_deg=6.0, lateral_range_m=0.03)


def test_trials_are_reproducible_from_the_seed():
    filters = (FilterSpec("cpf", "cpf"), FilterSpec("mpf-am", "am"))
    a = run_trial(TINY, filters, 5, 1)
    b = run_trial(TINY, filters, 5, 1)
    assert a.contact_index == b.contact_index
    assert np.array_equal(a.rmse_m, b.rmse_m)


def test_compare_part_writes_summary_and_figure(tmp_path):
    summary = run_part("compare", TINY, 3, 0, tmp_path, progress=False)
    written = json.loads((tmp_path / "summary.json").read_text())
    assert written["filters"].keys() == {"cpf", "mpf-am"}
    entry = written["filters"]["mpf-am"]
    for key in ("post_contact_rmse_cm", "post_contact_rmse_deg", "sampling_failure_rate",
                "sampling_failure_rate_correct_readings"):
        assert key in entry
    assert written["parameters"]["particles"] == 30
    assert (tmp_path / "compare_rmse.png").stat().st_size > 10_000
    assert summary["conditions"][0]["trials"] == 3


def test_a_user_polygon_runs_without_code_changes(tmp_path):
    obj = tmp_path / "wedge.yaml"
    obj.write_text("shape: polygon\nvertices_m: [[-0.03, -0.04], [0.04, 0.0], [-0.03, 0.04]]\n"
                   "height_m: 0.1\nmass_kg: 0.2\n")
    code = main(["experiment", "mpf", "--part", "compare", "--trials", "2",
                 "--object", str(obj), "--push-distance", "0.15", "--out",
                 str(tmp_path / "out"), "--no-progress"])
    assert code == 0
    assert "mpf-am" in json.loads((tmp_path / "out" / "summary.json").read_text())["filters"]


def test_bad_object_file_is_a_clear_error(tmp_path, capsys):
    obj = tmp_path / "bad.yaml"
    obj.write_text("shape: polygon\nvertices_m: [[0, 0], [1, 1]]\nheight_m: 0.1\n")
    assert main(["experiment", "mpf", "--object", str(obj), "--out", str(tmp_path)]) == 2
    assert "vertices_m" in capsys.readouterr().err
