"""The closed-loop study on the trial runner, with a stand-in for the Drake episode: the
episodes asked for, kept in trials.jsonl, resumed without running again, and a trials
file of other settings refused."""

import json
from types import SimpleNamespace

import pytest

import experiments.closedloop_study as study
from experiments.closedloop_study import ClosedLoopSettings, run_closedloop_study
from experiments.runner import Backend
from planning.hand.solution import HandSolveSettings


@pytest.fixture
def fake_episodes(monkeypatch):
    calls = []

    def episode(settings, solution, **kwargs):
        calls.append(settings.seed)
        success = settings.seed % 2 == 0
        return SimpleNamespace(summary={
            "success": success, "planning_ms": [1.0, 2.0], "infeasible_actions": 0,
            "infeasible_rejected": 0, "stop_reason": "goal" if success else "horizon",
            "final_distance_to_goal_m": 0.01, "estimator_rmse_m": {"mean": 0.02},
            "estimator_rmse_over_time": {"time_s": [0.0, 1.0], "rmse_m": [0.03, 0.02]}})

    monkeypatch.setattr(study, "run_episode", episode)
    monkeypatch.setattr(study, "_solution", lambda solver, cache: SimpleNamespace(
        timings={"solve": 1.0}, model=SimpleNamespace(world=None)))
    monkeypatch.setattr(study, "_shared_filter", lambda *args: None)
    return calls


def test_episodes_are_kept_and_a_resumed_study_runs_none_again(fake_episodes, tmp_path):
    settings = ClosedLoopSettings(policies=("qmdp", "pomdp"), trials=3)
    first = run_closedloop_study(settings, HandSolveSettings(), tmp_path,
                                 backend=Backend("serial"), progress=False)
    assert len(fake_episodes) == 6
    lines = (tmp_path / "trials.jsonl").read_text().splitlines()
    assert len(lines) == 1 + 6  # the header and one line per episode
    again = run_closedloop_study(settings, HandSolveSettings(), tmp_path,
                                 backend=Backend("serial"), resume=True, progress=False)
    assert len(fake_episodes) == 6  # nothing ran again
    assert json.dumps(again["policies"]) == json.dumps(first["policies"])
    assert first["policies"]["qmdp"]["trials"] == 3
    assert [e["belief"] for e in first["policies"]["pomdp"]["episodes"]] == [1, 2, 3]


def test_a_trials_file_of_other_settings_is_refused(fake_episodes, tmp_path):
    run_closedloop_study(ClosedLoopSettings(trials=2), HandSolveSettings(), tmp_path,
                         backend=Backend("serial"), progress=False)
    with pytest.raises(ValueError, match="seed"):
        run_closedloop_study(ClosedLoopSettings(trials=2, seed=5), HandSolveSettings(),
                             tmp_path, backend=Backend("serial"), resume=True, progress=False)
