"""``cmanip experiment configest`` and ``cmanip bench configest`` end to end, small."""

import json

import pytest

from cmanip.cli import main
from cmanip.config import load_config
from experiments.configest_study import ConfigestSettings, hypotheses


def test_configest_study_writes_the_summary_the_issue_asks_for(tmp_path):
    out = tmp_path / "ce"
    assert main(["experiment", "configest", "--arm", "2dof", "--trials", "2", "--out",
                 str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    filters = summary["arms"]["2dof"]
    for kind in ("cpf", "mpf-uniform", "mpf-particle", "mpf-ball", "mpf-explicit"):
        entry = filters[kind]
        for key in ("rmse_rad_mean", "rmse_rad_mean_ci95", "rmse_rad_final",
                    "rmse_rad_final_ci95"):
            assert entry[key] >= 0
        assert ("projection_failure_rate" in entry) == (kind != "cpf")
        if kind != "cpf":  # paired with the CPF on the same experiments
            assert abs(entry["vs_cpf_rad_mean"] - (entry["rmse_rad_mean"]
                                                   - filters["cpf"]["rmse_rad_mean"])) < 1e-9
    assert "H2_alike_at_2dof" in summary["hypotheses"]
    assert (out / "configest.png").stat().st_size > 10_000
    replayed = load_config(ConfigestSettings, out / "config.yaml")  # replays the run
    assert replayed == ConfigestSettings(arms=("2dof",), trials=2)


def test_bad_arm_is_a_clear_error(tmp_path, capsys):
    assert main(["experiment", "configest", "--arm", "4dof", "--trials", "2", "--out",
                 str(tmp_path)]) == 2
    assert "unknown arms name" in capsys.readouterr().err
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: planar\nlinks_m: [0.5]\nlink_radius_m: 0.01\n")
    assert main(["bench", "configest", "--arm", str(bad)]) == 2
    assert "bad.yaml" in capsys.readouterr().err


def test_bench_reports_update_times_and_the_signed_distance_speedup(tmp_path):
    report = tmp_path / "bench.json"
    assert main(["bench", "configest", "--arm", "2dof", "--json", str(report)]) == 0
    entry = json.loads(report.read_text())["2dof"]
    assert entry["cpf_update_ms"] > 0 and entry["mpf_ball_update_ms"] > 0
    assert entry["mpf_ball_history_contact_update_ms"] > 0
    assert entry["history_density_steps"] == entry["updates"] - 1
    assert entry["history_density_ms_last_step"] > 0
    assert entry["lift_ms_last_step"] > entry["lift_path_ms_last_step"] > 0
    assert entry["lift_cost_ratio_to_density"] > 1
    assert set(entry["root_finders"]) == {"gd", "lm"}
    assert entry["signed_distance_speedup"] > 1


def test_configest_run_refuses_bad_input_before_building(tmp_path, capsys):
    assert main(["configest", "run", "--arm", "2dof", "--out", str(tmp_path)]) == 2
    assert "needs a 'herb' arm" in capsys.readouterr().err
    assert main(["configest", "run", "--tactile-error-rate", "2", "--out",
                 str(tmp_path)]) == 2
    assert "(--tactile-error-rate) must be in [0, 1]" in capsys.readouterr().err
    assert main(["configest", "run", "--particles", "5", "--out", str(tmp_path)]) == 2
    assert "(--dual-particles) must be in [1, particles)" in capsys.readouterr().err
    assert main(["configest", "run", "--dual-particles", "0", "--out", str(tmp_path)]) == 2
    assert "got 0 with 100 particles" in capsys.readouterr().err
    assert main(["configest", "run", "--mixing-rate", "1.5", "--out", str(tmp_path)]) == 2
    assert "(--mixing-rate) must be in [0, 1]" in capsys.readouterr().err
    assert main(["configest", "run", "--process-noise", "-0.01", "--out", str(tmp_path)]) == 2
    assert "(--process-noise) must be in [0, 0.5] rad" in capsys.readouterr().err
    assert main(["configest", "run", "--outlier-gate", "3", "--out", str(tmp_path)]) == 2
    assert "--outlier-gate must be < 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as usage:
        main(["configest", "run", "--metric", "bogus", "--out", str(tmp_path)])
    assert usage.value.code == 2


def test_the_beyond_thesis_variants_are_settings_and_bad_ones_clear_errors(tmp_path, capsys):
    config = tmp_path / "ce.yaml"
    config.write_text("constraints: full\ndual_share: density\n")
    assert load_config(ConfigestSettings, config) == ConfigestSettings(
        constraints="full", dual_share="density")
    config.write_text("dual_share: half\n")
    assert main(["experiment", "configest", "--config", str(config), "--arm", "2dof",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "ce.yaml" in err and "dual_share" in err
    with pytest.raises(SystemExit) as exit_:
        main(["experiment", "configest", "--dual-share", "some", "--arm", "2dof",
              "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2
    assert "--dual-share: invalid choice" in capsys.readouterr().err


def _wam_entry(mean, ci, vs=None, vs_ci=None, paired=None):
    """A filter's summary entry: mean RMSE (rad) and half-width, its paired difference to
    the CPF, and ``paired`` {other: (diff, half-width)}."""
    e = {"rmse_rad_mean": mean, "rmse_rad_mean_ci95": ci}
    if vs is not None:
        e.update(vs_cpf_rad_mean=vs, vs_cpf_rad_mean_ci95=vs_ci)
    if paired is not None:
        e["paired_rad_mean"] = {k: {"diff": d, "ci95": h} for k, (d, h) in paired.items()}
    return e


def test_h1_is_judged_on_the_paired_difference_to_the_cpf():
    # consistently 0.14 below the CPF on the same experiments, inside the unpaired spread
    still = {"mpf-uniform": (0.0, 0.01), "mpf-particle": (0.0, 0.01), "mpf-ball": (0.0, 0.01)}
    arm = {"cpf": _wam_entry(1.55, 0.12),
           "mpf-uniform": _wam_entry(3.7, 0.2, 2.1, 0.2, still),
           "mpf-particle": _wam_entry(1.41, 0.16, -0.13, 0.22, still),
           "mpf-ball": _wam_entry(1.40, 0.11, -0.14, 0.13, still)}
    h = hypotheses({"wam": arm})
    assert h["H1_mpf_beats_cpf"] == {"wam": True}
    assert h["H1_mpf_beats_cpf_unpaired"] == {"wam": False}
    arm["mpf-ball"] = _wam_entry(1.40, 0.11, -0.14, 0.15, still)
    assert hypotheses({"wam": arm})["H1_mpf_beats_cpf"] == {"wam": False}
    assert hypotheses({"wam": arm})["H4_ball_best_on_wam_unpaired"]


def test_h3_and_h4_are_judged_on_the_paired_differences_between_variants():
    # the 3-DOF default study's shape: Ball 0.15 below Uniform on the same experiments,
    # its own interval touching Uniform's; Particle 0.09 below Ball, consistently
    def arm(particle_vs_ball):
        return {"cpf": _wam_entry(1.35, 0.1),
                "mpf-uniform": _wam_entry(1.44, 0.08, 0.09, 0.1, {
                    "mpf-particle": (0.24, 0.08), "mpf-ball": (0.15, 0.07)}),
                "mpf-particle": _wam_entry(1.20, 0.09, -0.15, 0.1, {
                    "mpf-uniform": (-0.24, 0.08), "mpf-ball": particle_vs_ball}),
                "mpf-ball": _wam_entry(1.29, 0.08, -0.06, 0.1, {
                    "mpf-uniform": (-0.15, 0.07),
                    "mpf-particle": (-particle_vs_ball[0], particle_vs_ball[1])})}

    h = hypotheses({"3dof": arm((-0.09, 0.05)), "wam": arm((-0.09, 0.05))})
    assert h["H3_particle_ball_beat_uniform"] == {"3dof": True, "wam": True}
    assert h["H3_particle_ball_beat_uniform_unpaired"] == {"3dof": False, "wam": False}
    assert not h["H4_ball_best_on_wam"]  # Particle is below Ball beyond the interval
    assert hypotheses({"wam": arm((-0.09, 0.12))})["H4_ball_best_on_wam"]
    assert hypotheses({"wam": arm((+0.09, 0.05))})["H4_ball_best_on_wam"]


def test_h2_is_judged_on_the_mean_and_on_the_final_rmse_apart():
    def entry(mean, final):  # (value, 95 % half-width) each
        return {"rmse_rad_mean": mean[0], "rmse_rad_mean_ci95": mean[1],
                "rmse_rad_final": final[0], "rmse_rad_final_ci95": final[1],
                "vs_cpf_rad_mean": -0.3, "vs_cpf_rad_mean_ci95": 0.1}

    # the 2-DOF figures of the default study: alike at the end, not over time
    arm = {"cpf": entry((2.45, 0.1), (2.36, 0.13)),
           "mpf-uniform": entry((2.11, 0.09), (0.10, 0.06)),
           "mpf-particle": entry((1.91, 0.10), (0.16, 0.11)),
           "mpf-ball": entry((2.10, 0.09), (0.12, 0.09)),
           "mpf-explicit": entry((2.14, 0.09), (0.058, 0.003))}
    h = hypotheses({"2dof": arm})
    assert not h["H2_alike_at_2dof"] and h["H2_alike_at_2dof_final"]
    arm["mpf-explicit"] = entry((2.14, 0.09), (0.34, 0.13))  # as with the history density
    assert not hypotheses({"2dof": arm})["H2_alike_at_2dof_final"]


def test_an_unknown_proprioception_is_a_clear_error(capsys):
    from diagrams.herb.configest_episode import ConfigestEpisodeSettings

    for settings in (ConfigestSettings, ConfigestEpisodeSettings):
        with pytest.raises(ValueError, match="proprioception must be one of first, steps"):
            settings(proprioception="all")
    with pytest.raises(SystemExit) as exit_:
        main(["configest", "run", "--proprioception", "all", "--out", "x"])
    assert exit_.value.code == 2 and "--proprioception" in capsys.readouterr().err
