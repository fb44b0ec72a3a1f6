"""Runs configured from files: ``cmanip run --config FILE``, the resolved ``config.yaml``
written beside the outputs, and its replay."""

import json

import pytest
import yaml

from cmanip.cli import main
from cmanip.config import RunConfig, load_config
from diagrams.herb.settings import EpisodeSettings
from models.config import ConfigError
from models.settings import settings_to_dict, write_settings
from planning.hand.precontact import PreContactSettings

TIMINGS = ("wall_time_s", "real_time_factor", "planning_ms", "planning_ms_median")


def _small_run(small_hand_solution, tmp_path):
    """A short episode whose pre-contact search looks 3 steps ahead, so it ends by its
    depth, long before its wall-time limit (which would make the run depend on the
    machine's speed)."""
    _, solver, cache = small_hand_solution
    episode = EpisodeSettings(object_name="small_box", policy="pomdp", estimator="cpf",
                              particles=60, horizon=3, belief_mean=(0.30, 0.0, 0.0),
                              precontact=PreContactSettings(horizon=3, time_limit_s=60.0),
                              seed=4)
    path = tmp_path / "small.yaml"
    write_settings(RunConfig(episode, solver, str(cache)), path)
    return path


def test_a_run_replays_from_its_config_yaml(small_hand_solution, tmp_path, capsys):
    config = _small_run(small_hand_solution, tmp_path)
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["run", "--config", str(config), "--seed", "5", "--out", str(first),
                 "--no-progress"]) == 0
    resolved = yaml.safe_load((first / "config.yaml").read_text())
    assert resolved["episode"]["seed"] == 5 and resolved["episode"]["particles"] == 60
    assert main(["run", "--config", str(first / "config.yaml"), "--out", str(second),
                 "--no-progress"]) == 0
    a = json.loads((first / "summary.json").read_text())
    b = json.loads((second / "summary.json").read_text())
    for key in TIMINGS:  # wall-clock measurements, the only things allowed to differ
        a.pop(key), b.pop(key)
    assert a == b
    assert (first / "config.yaml").read_text() == (second / "config.yaml").read_text()


def test_options_override_the_file_and_defaults_are_the_settings_own(tmp_path):
    path = tmp_path / "run.yaml"
    path.write_text("episode:\n  particles: 80\n  horizon: 7\n")
    config = load_config(RunConfig, path)
    assert config.episode.particles == 80 and config.episode.horizon == 7
    assert config.episode.policy == EpisodeSettings().policy
    assert settings_to_dict(load_config(RunConfig, None)) == settings_to_dict(RunConfig())


@pytest.mark.parametrize("text, field", [
    ("episode:\n  particles: many\n", "episode.particles"),
    ("episode:\n  partcles: 10\n", "episode.partcles"),
    ("solver:\n  solve_seconds: -1\n", "solver"),
    ("episode:\n  belief_mean: [0.3, 0.0]\n", "episode.belief_mean"),
    ("episode:\n  estimator_outlier_log_evidence: 2.0\n", "episode"),
    ("episode:\n  time_step_s: 0\n", "time_step_s"),
    ("episode:\n  hand_speed_m_per_s: -0.1\n", "hand_speed_m_per_s"),
    ("episode:\n  belief_std: [0.05, .nan, 0.1]\n", "belief_std"),
    ("episode:\n  precontact:\n    contact_stop: 1.5\n", "contact_stop"),
    ("solver:\n  solve_trials: 0\n", "solve_trials"),
    ("episode:\n  hand_speed_m_per_s: 1.0e+12\n", "hand_speed_m_per_s"),
    ("solver:\n  spec:\n    trust_x_m: [0.0, 1.0e+12]\n", "trust_x_m"),
])
def test_a_bad_config_names_the_file_and_field(tmp_path, capsys, text, field):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(RunConfig, path)
    assert str(path) in str(err.value) and field in str(err.value)
    assert main(["run", "--config", str(path), "--out", str(tmp_path / "o")]) == 2
    assert str(path) in capsys.readouterr().err


def test_the_estimators_outlier_gate_is_a_setting_and_reaches_the_filter(tmp_path):
    from diagrams.herb.closed_loop import estimator_filter
    from models.planar.world import PlanarWorld

    path = tmp_path / "gated.yaml"
    path.write_text("episode:\n  estimator_outlier_log_evidence: -30\n")
    gate = load_config(RunConfig, path).episode.estimator_outlier_log_evidence
    assert gate == -30.0
    world = PlanarWorld.load("small_box", "medium")
    assert estimator_filter("cpf", world, gate).outlier_log_evidence == -30.0
    assert estimator_filter("cpf", world).outlier_log_evidence is None


def test_the_episode_and_the_model_must_push_the_same_object(tmp_path):
    path = tmp_path / "mismatch.yaml"
    path.write_text("episode:\n  object_name: small_box\n")
    with pytest.raises(ConfigError, match="planning model is solved for 'bottle'"):
        load_config(RunConfig, path)


@pytest.mark.parametrize("command", [["run"], ["configest", "run"]])
def test_a_bad_outlier_gate_is_named_as_its_flag(command, tmp_path, capsys):
    assert main([*command, "--outlier-gate", "3", "--out", str(tmp_path / "x")]) == 2
    assert "--outlier-gate must be < 0, got 3.0" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_the_lat_despot_options_reach_the_episode_settings():
    from cmanip.cli import build_parser
    from cmanip.run import resolve_run

    args = build_parser().parse_args(["run", "--planner", "lat-despot", "--lat-despot-model",
                                      "continuous", "--lat-despot-outside", "return",
                                      "--out", "x"])
    episode = resolve_run(args).episode
    assert (episode.planner, episode.lat_despot_model, episode.lat_despot_outside) == (
        "lat-despot", "continuous", "return")


@pytest.mark.parametrize("flags, message", [
    (["--metric", "kernel"], "needs the joint metric, got 'kernel'"),
    (["--dual-share", "density"], "goes with the fixed or evidence dual share"),
])
def test_the_history_dual_density_refuses_what_it_cannot_combine(flags, message, tmp_path,
                                                                 capsys):
    out = tmp_path / "x"
    assert main(["configest", "run", "--dual-density", "history", *flags,
                 "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()
