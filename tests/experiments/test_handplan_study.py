"""The hand-relative planning study end to end, on a tiny problem."""

import json
from dataclasses import replace

import numpy as np
import pytest

from cmanip.cli import main
from experiments.handplan_study import HandplanSettings, run_study
from models.planar.hand import PlanarHand
from planning.hand.discretization import HandProblemSpec
from planning.hand.precontact import PreContactSettings
from planning.pomdp.cassandra import read_pomdp

TINY = HandplanSettings(
    trials=4, seed=1, solve_seconds=2.0, horizon=4, belief_count=3, belief_particles=100,
    precontact_particles=30, precontact=PreContactSettings(time_limit_s=2.0),
    spec=HandProblemSpec(trust_x_m=(0.0, 0.22), trust_y_m=(-0.08, 0.08), samples_per_state=2))


def test_every_part_writes_its_summary_and_figures(tmp_path):
    summary = run_study("all", TINY, tmp_path)
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["part"] == "all"
    for key in ("post_contact", "full"):
        for name in ("QMDP", "POMDP"):
            r = summary[key][name]
            lo, hi = r["success_rate_ci95"]
            assert 0 <= lo <= r["success_rate"] <= hi <= 1
            assert len(r["success_over_time"]) == TINY.horizon + 1 + (15 if key == "full" else 0)
            assert r["discounted_value"] <= 0
    assert summary["post_contact_discrete"]["POMDP"]["episodes"] == 2 * TINY.trials
    assert len(summary["full"]["POMDP"]["plans"]) == TINY.belief_count
    coverage = summary["coverage"]
    assert coverage["fingertips"]["observations"]["feasible"] == 3  # as the thesis
    assert coverage["links"]["observations"]["possible"] == 31
    for png in ("problem.png", "post_contact_value.png", "post_contact_success.png",
                "full_success.png", "coverage.png"):
        assert (tmp_path / png).stat().st_size > 0
    model = read_pomdp(tmp_path / "hand_fingertips.pomdp")
    assert model.shape[1:] == (5, 4)


def test_same_seed_same_results_on_any_backend_and_resumed(tmp_path):
    """With a trial budget (not wall time) for the solver, a run is a function of its seed:
    serial or on two worker processes (which rebuild the model and load the policies), and
    resumed (the saved policy reused, not solved again; the finished evaluations kept)."""
    from experiments.runner import Backend

    settings = replace(TINY, trials=3, solve_seconds=60.0, solve_trials=20)
    a = run_study("post-contact", settings, tmp_path / "a", progress=False)
    b = run_study("post-contact", settings, tmp_path / "b", progress=False,
                  backend=Backend("processes", 2))
    assert a["post_contact"] == b["post_contact"]
    assert not b["models"]["fingertips"]["solver_reused"]
    c = run_study("post-contact", settings, tmp_path / "b", progress=False, resume=True)
    assert c["post_contact"] == a["post_contact"]
    assert c["models"]["fingertips"]["solver_reused"]


def test_links_layout_has_one_sensor_per_planar_link():
    hand = PlanarHand.load("links")
    assert hand.sensor_count == 5
    assert np.array_equal(np.unique(hand.sensor_of_segment), np.arange(5))
    fingertips = PlanarHand.load("fingertips")
    tips = fingertips.sensor_segments.reshape(-1, 2)
    assert fingertips.sensor_count == 2 and (tips[:, 0] > 0.06).all()  # on the distal links


def test_cli_rejects_bad_arguments(capsys):
    assert main(["experiment", "handplan", "--trials", "1", "--out", "x"]) == 2
    assert "--trials" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["experiment", "handplan", "--part", "nope", "--out", "x"])


def test_settings_and_parts_reject_bad_values(tmp_path):
    with pytest.raises(ValueError, match="trials"):
        HandplanSettings(trials=0)
    with pytest.raises(ValueError, match="part must be one of"):
        run_study("everything", TINY, tmp_path)
