"""Studies configured from files: ``cmanip experiment mpf|handplan|visuotactile --config``,
the options that override the file, the ``config.yaml`` each writes, and its replay."""

import json

import pytest
import yaml

from cmanip.cli import build_parser, main
from cmanip.config import HandplanStudyConfig, MpfStudyConfig, VisuotactileStudyConfig
from cmanip.experiment import resolve_handplan, resolve_mpf, resolve_visuotactile
from experiments.handplan_study import quick_settings
from models.config import ConfigError


def _args(*argv):
    return build_parser().parse_args(["experiment", *argv, "--out", "unused"])


def test_an_mpf_study_replays_from_its_config_yaml(tmp_path, capsys):
    first, second = tmp_path / "first", tmp_path / "second"
    assert main(["experiment", "mpf", "--trials", "2", "--seed", "3", "--push-distance",
                 "0.05", "--out", str(first), "--no-progress"]) == 0
    resolved = yaml.safe_load((first / "config.yaml").read_text())
    assert resolved["seed"] == 3 and resolved["trial"]["push_distance_m"] == 0.05
    assert main(["experiment", "mpf", "--config", str(first / "config.yaml"), "--out",
                 str(second), "--no-progress"]) == 0
    assert (json.loads((first / "summary.json").read_text())
            == json.loads((second / "summary.json").read_text()))
    assert (first / "config.yaml").read_text() == (second / "config.yaml").read_text()


def test_options_override_the_file_field_by_field(tmp_path):
    path = tmp_path / "mpf.yaml"
    path.write_text("trials: 40\ntrial:\n  particles: 50\n  sensors: high\n")
    config = resolve_mpf(_args("mpf", "--config", str(path), "--sensors", "low"))
    assert (config.trials, config.trial.particles, config.trial.sensors) == (40, 50, "low")
    assert config.trial.object == MpfStudyConfig().trial.object  # the dataclass default


def test_handplan_options_apply_on_top_of_quick(tmp_path):
    quick = quick_settings(HandplanStudyConfig().study)
    config = resolve_handplan(_args("handplan", "--quick", "--horizon", "7"))
    assert config.study.horizon == 7
    assert config.study.spec == quick.spec
    assert config.study.precontact.time_limit_s == quick.precontact.time_limit_s
    config = resolve_handplan(_args("handplan", "--plan-seconds", "3",
                                    "--search-until-contact", "--part", "full"))
    assert config.part == "full"
    assert config.study.precontact.time_limit_s == 3.0
    assert config.study.precontact.trust_mass_stop is None


def test_a_handplan_config_replays_what_was_resolved(tmp_path):
    from cmanip.config import write_config
    from models.settings import load_settings

    config = resolve_handplan(_args("handplan", "--quick", "--trials", "9", "--seed", "2"))
    path = write_config(config, tmp_path)
    assert load_settings(HandplanStudyConfig, path) == config
    replayed = resolve_handplan(_args("handplan", "--config", str(path)))
    assert replayed == config


def test_visuotactile_reads_its_rig_once_at_the_top(tmp_path):
    config = resolve_visuotactile(_args("visuotactile", "--trials", "3", "--part", "all"))
    assert config == VisuotactileStudyConfig(
        "all", VisuotactileStudyConfig().study.__class__(trials=3))
    missing = tmp_path / "nowhere.yaml"
    with pytest.raises(ConfigError, match="nowhere.yaml"):
        resolve_visuotactile(_args("visuotactile", "--rig", str(missing)))


@pytest.mark.parametrize("study, text, field", [
    ("mpf", "part: everything\n", "part"),
    ("mpf", "trial:\n  push_distance_m: 5\n", "trial"),
    ("mpf", "trial:\n  particle: 5\n", "trial.particle"),
    ("handplan", "study:\n  spec:\n    discount: high\n", "study.spec.discount"),
    ("visuotactile", "study:\n  trials: [1]\n", "study.trials"),
    ("latdespot", "rel:\n  continuous_rollout: fast\n", "continuous_rollout"),
    ("latdespot", "rel:\n  continuous_outside: wrap\n", "continuous_outside"),
    ("latdespot", "rel:\n  continuous_despot_trials: -3\n", "continuous_despot_trials"),
    ("latdespot", "rel:\n  continuous_despot_trials: many\n", "rel.continuous_despot_trials"),
])
def test_a_bad_study_config_names_the_file_and_field(tmp_path, capsys, study, text, field):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["experiment", study, "--config", str(path), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and field in err


@pytest.mark.parametrize("option", [["--workers", "0"], ["--continuous-rollout", "fast"],
                                    ["--continuous-despot-trials", "0"],
                                    ["--continuous-outside", "wrap"]])
def test_bad_latdespot_options_are_usage_errors(tmp_path, capsys, option):
    with pytest.raises(SystemExit) as exit_:
        status = main(["experiment", "latdespot", *option, "--out", str(tmp_path / "o")])
        raise SystemExit(status)
    assert exit_.value.code == 2
    err = capsys.readouterr().err  # names the option, or the setting it overrides
    assert option[0] in err or option[0][2:].replace("-", "_") in err
