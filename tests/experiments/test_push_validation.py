"""The planar pushing model against Drake's hydroelastic simulation (slow: 20 pushes)."""

import numpy as np
import pytest

from experiments.push_validation import run_push_validation, uniform_pressure_radius


def test_uniform_pressure_radius_of_a_disk_is_two_thirds_of_its_radius():
    a = 2 * np.pi * np.arange(256) / 256
    disk = 0.09 * np.column_stack([np.cos(a), np.sin(a)])
    assert uniform_pressure_radius(disk) == pytest.approx(0.06, rel=0.01)


@pytest.mark.slow
def test_rotation_direction_agrees_with_drake_in_every_case(tmp_path):
    summary = run_push_validation(tmp_path, progress=False)
    assert summary["case_count"] >= 20
    assert summary["rotation_direction_agreement"] == summary["case_count"]
    assert summary["position_difference_m_median"] < 0.02
    assert (tmp_path / "push_validation.png").exists()


def test_pushval_refuses_a_push_longer_than_the_table_allows(tmp_path, capsys):
    from cmanip.cli import main

    assert main(["experiment", "pushval", "--push-distance", "1.0", "--out", str(tmp_path)]) == 2
    assert "--push-distance" in capsys.readouterr().err


def test_pushval_runs_its_cases_as_trials_and_a_resumed_run_reruns_none(tmp_path,
                                                                        monkeypatch):
    import experiments.push_validation as pushval

    monkeypatch.setattr(pushval, "LATERAL_OFFSETS_M", (0.0,))
    monkeypatch.setattr(pushval, "ORIENTATIONS_DEG", (0.0, 20.0))
    whole = run_push_validation(tmp_path, push_distance_m=0.05, progress=False)
    assert whole["case_count"] == 2
    assert (tmp_path / "trials.jsonl").read_text().count("\n") == 3  # header and 2 cases

    def no_more_pushes(*args):
        raise AssertionError("a stored case ran again")

    monkeypatch.setattr(pushval, "push_case", no_more_pushes)
    again = run_push_validation(tmp_path, push_distance_m=0.05, resume=True, progress=False)
    assert again == whole
    with pytest.raises(ValueError, match="other settings"):
        run_push_validation(tmp_path, push_distance_m=0.06, resume=True, progress=False)
