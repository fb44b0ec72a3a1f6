"""``cmanip experiment latdespot --part rel`` end to end on a small problem, and the ch. 7
problem file: four 1 cm actions, no separate contact states."""

import json

import numpy as np
import pytest
import yaml

from cmanip.cli import main
from models.config import ConfigError
from models.planar.world import PlanarWorld
from planning.hand.discretization import HandDiscretization, HandProblemSpec


def small_lattice_config(tmp_path):
    """A study configuration with a small lattice (its IK table cached under tmp_path)."""
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"scenes": {
        "lattice_x_range_m": [-0.04, 0.10], "lattice_y_range_m": [-0.12, 0.12],
        "cache_dir": str(tmp_path / "cache")}}))
    return config


def test_the_chapter_7_problem_has_four_moves_and_one_grid():
    spec = HandProblemSpec.load("rel_ch7")
    assert spec.action_names == ("forward", "back", "left", "right")
    np.testing.assert_allclose(spec.action_vectors()[1], [-0.01, 0.0, 0.0])
    assert spec.max_action_m == pytest.approx(0.01)
    world = PlanarWorld.load("bottle", sensors="fingertips", error_rate=0.0)
    disc = HandDiscretization(world, spec)
    assert disc.shape_xy == (20, 44) and disc.contact_count == 0
    touching = np.array([[0.09, 0.0, 0.0]])  # the bottle against the palm region
    assert disc.index(touching)[0] < disc.free_count  # a grid cell, contact or not


def test_problem_files_name_bad_actions(refused):
    refused(HandProblemSpec.load, "actions: {forward: [1]}\n", "actions.forward")
    refused(HandProblemSpec.load, "actions: {}\n", "actions")
    with pytest.raises(ConfigError, match="unknown problems name"):
        HandProblemSpec.load("no_such_problem")


def test_rel_runs_end_to_end_and_replays_its_config(tmp_path, capsys, small_problem):
    problem = small_problem
    out = tmp_path / "rel"
    assert main(["experiment", "latdespot", "--part", "rel", "--trials", "4", "--horizon",
                 "6", "--problem", str(problem), "--solve-trials", "10", "--solve-seconds",
                 "30", "--despot-trials", "5", "--continuous-despot-trials", "5",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["rel"]) == {"rel-qmdp", "rel-sarsop", "rel-despot",
                                   "rel-despot-continuous"}
    continuous = summary["rel"]["rel-despot-continuous"]
    assert continuous["value_model"] == "continuous" and continuous["decisions"] == 4 * 6
    assert continuous["despot_trials_median"] <= 5
    assert continuous["discounted_value"] == continuous["continuous_discounted_value"]
    for entry in summary["rel"].values():
        for key in ("discounted_value", "discounted_value_ci95", "success_rate",
                    "success_rate_ci95", "planning_ms_median"):
            assert key in entry
        assert len(entry["success_over_time"]) == 7
    assert summary["model"]["actions"] == ["forward", "back", "left", "right"]
    assert (out / "rel_value.png").is_file() and (out / "rel_success.png").is_file()
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["rel"]["trials"] == 4 and config["rel"]["problem"] == str(problem)
    assert config["rel"]["continuous_despot_trials"] == 5
    assert "rel-despot" in capsys.readouterr().out


def test_continuous_episodes_do_not_depend_on_the_worker_count(small_problem):
    from experiments.latdespot_continuous import run_continuous_episodes
    from experiments.latdespot_study import RelSettings, build_rel_problem
    from experiments.runner import Backend

    settings = RelSettings(trials=3, horizon=4, problem=str(small_problem),
                           continuous_despot_trials=3)
    alone = run_continuous_episodes(settings, build_rel_problem, backend=Backend("serial"),
                                    progress=False)
    spread = run_continuous_episodes(settings, build_rel_problem,
                                     backend=Backend("processes", 2), progress=False)
    for a, b in zip(alone, spread, strict=True):
        np.testing.assert_array_equal(a.in_goal, b.in_goal)
        assert a.discounted_return == b.discounted_return


def test_scenes_and_bound_run_end_to_end(tmp_path, capsys, small_problem):
    config = small_lattice_config(tmp_path)
    out = tmp_path / "lat"
    assert main(["experiment", "latdespot", "--config", str(config), "--part", "bound",
                 "--scene", "right_obstacles", "--trials", "2", "--horizon", "4",
                 "--problem", str(small_problem), "--solve-trials", "5",
                 "--despot-trials", "3", "--lat-despot-trials", "3",
                 "--policy-trials", "lat-despot-pb=2", "rel-despot=3", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    entries = summary["scenes"]["right_obstacles"]
    assert set(entries) == {"rel-qmdp", "rel-sarsop", "rel-despot", "lift-qmdp",
                            "lift-sarsop", "lat-despot", "lat-despot-pb"}
    for entry in entries.values():
        for key in ("success_rate", "success_rate_ci95", "infeasible_rate", "discounted_value",
                    "discounted_value_ci95", "planning_ms_median", "planning_ms_p99"):
            assert key in entry
    for name in ("lift-qmdp", "lift-sarsop", "lat-despot", "lat-despot-pb"):
        assert entries[name]["infeasible_rate"] == 0.0  # they check the lattice first
    assert "rel" not in summary  # the bound's Rel episodes start from the scene's belief
    assert set(summary["hypotheses"]) == {"H2", "H3", "H4", "feasible_only"}
    bound = summary["bound"]["scenes"]["right_obstacles"]
    assert bound["best_lat_policy"] in entries and isinstance(bound["holds"], bool)
    assert set(bound["rel_pomdp"]) == {"rel-sarsop", "rel-despot"}
    assert all(e["trials"] == 2 for e in bound["rel_pomdp"].values())
    upper = bound["rel_upper_bounds"]["mdp_horizon"]
    assert np.isfinite(upper) and -4.0 <= upper <= 0.0  # 4 steps of rewards in [-1, 0]
    assert isinstance(summary["bound"]["below_upper_bounds"], bool)
    keys = [json.loads(line)["key"] for line in
            (out / "trials.jsonl").read_text().splitlines()[1:]]
    assert sorted(k for k in keys if "/rel/" in k) == [
        f"right_obstacles/{p}/rel/{j}" for p in ("rel-despot", "rel-sarsop") for j in (0, 1)]
    assert (out / "lat_scenes.png").is_file() and (out / "lat_success_time.png").is_file()
    assert (out / "lattice_right_obstacles.png").is_file() and (out / "lat_bound.png").is_file()
    config_out = yaml.safe_load((out / "config.yaml").read_text())
    assert config_out["part"] == "bound" and config_out["scenes"]["scenes"] == ["right_obstacles"]
    assert config_out["scenes"]["lat_despot_trials"] == 3
    assert "bound of sec. 7.3.5" in capsys.readouterr().out


def test_policy_trials_give_a_costly_policy_fewer_episodes():
    from experiments.latdespot_scenes import SceneSettings

    scenes = SceneSettings(policy_trials=("lat-despot-pb=20", "rel-despot=500"))
    assert scenes.trials_of("lat-despot-pb", 200) == 20
    assert scenes.trials_of("rel-despot", 200) == 200  # never more than the study's
    assert scenes.trials_of("lat-despot", 200) == 200
    for bad in ("lat-despot-pb", "oracle=3", "lat-despot=1", "lat-despot=x"):
        with pytest.raises(ValueError, match="POLICY=N"):
            SceneSettings(policy_trials=(bad,))


def test_scene_options_are_checked(tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["experiment", "latdespot", "--part", "scenes", "--scene", "no_such_scene",
                 "--out", str(out)]) == 2
    assert "no_such_scene" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["experiment", "latdespot", "--part", "scenes", "--policies", "oracle",
              "--out", str(out)])
    assert exit_.value.code == 2
    assert main(["experiment", "latdespot", "--part", "scenes", "--policy-trials",
                 "lat-despot-pb:20", "--out", str(out)]) == 2
    assert "POLICY=N" in capsys.readouterr().err


def test_the_policies_option_selects_the_scene_policies():
    from cmanip.cli import build_parser
    from cmanip.experiment import resolve_latdespot

    args = build_parser().parse_args(["experiment", "latdespot", "--part", "scenes",
                                      "--policies", "lat-despot", "lift-sarsop",
                                      "--lat-despot-trials", "0", "--out", "x"])
    config = resolve_latdespot(args)
    assert config.scenes.policies == ("lat-despot", "lift-sarsop")
    assert config.scenes.lat_despot_trials is None  # 0: the wall-clock cap alone


def test_policies_all_is_the_default_set_even_over_a_config(tmp_path):
    """A study's config.yaml names the policies it ran; ``--policies all`` over it asks for
    the default set, not the file's."""
    from cmanip.cli import build_parser
    from cmanip.experiment import resolve_latdespot
    from experiments.latdespot_scenes import DEFAULT_POLICIES

    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"scenes": {"policies": ["lat-despot"]}}))
    parse = build_parser().parse_args
    args = parse(["experiment", "latdespot", "--config", str(config), "--out", "x"])
    assert resolve_latdespot(args).scenes.policies == ("lat-despot",)
    args = parse(["experiment", "latdespot", "--config", str(config), "--policies", "all",
                  "--out", "x"])
    assert resolve_latdespot(args).scenes.policies == DEFAULT_POLICIES


def test_a_resumed_scenes_part_reuses_the_solved_policy_and_the_episodes(tmp_path,
                                                                         small_problem):
    """Part ``scenes`` keeps each episode in trials.jsonl and its solved policy in
    solved_rel.npz; resumed with one more trial it runs only the new episodes and agrees
    with a whole run of that many."""
    config = small_lattice_config(tmp_path)
    common = ["experiment", "latdespot", "--config", str(config), "--part", "scenes",
              "--scene", "right_obstacles", "--policies", "lift-qmdp", "lat-despot",
              "--horizon", "4", "--problem", str(small_problem), "--solve-trials", "5",
              "--lat-despot-trials", "3", "--backend", "serial", "--no-progress"]
    out, whole = tmp_path / "resumed", tmp_path / "whole"
    assert main([*common, "--trials", "2", "--out", str(out)]) == 0
    assert (out / "solved_rel.npz").is_file()
    assert len((out / "trials.jsonl").read_text().splitlines()) == 1 + 2 * 2 * 2
    assert main([*common, "--trials", "3", "--resume", "--out", str(out)]) == 0
    assert len((out / "trials.jsonl").read_text().splitlines()) == 1 + 2 * 2 * 3
    resumed = json.loads((out / "summary.json").read_text())
    assert resumed["model"]["sarsop_reused_from"].endswith("solved_rel.npz")
    assert main([*common, "--trials", "3", "--out", str(whole)]) == 0
    fresh = json.loads((whole / "summary.json").read_text())
    for policy, entry in fresh["scenes"]["right_obstacles"].items():
        again = resumed["scenes"]["right_obstacles"][policy]
        for key in ("discounted_value", "success_rate", "infeasible_rate", "trials"):
            assert again[key] == entry[key], (policy, key)


def test_lat_despot_on_the_continuous_model_is_asked_for_by_name(tmp_path, small_problem):
    """``lat-despot-continuous`` is not in the default set; asked for, it runs on the
    continuous model alone (one episode per trial, not two), tracks the object with the MPF,
    never takes an infeasible action, and is valued on the continuous model."""
    from experiments.latdespot_scenes import DEFAULT_POLICIES, SceneSettings

    assert "lat-despot-continuous" not in SceneSettings().policies == DEFAULT_POLICIES
    config = small_lattice_config(tmp_path)
    out = tmp_path / "lat"
    assert main(["experiment", "latdespot", "--config", str(config), "--part", "scenes",
                 "--scene", "right_obstacles", "--policies", "lift-qmdp",
                 "lat-despot-continuous", "--trials", "2", "--horizon", "4",
                 "--problem", str(small_problem), "--solve-trials", "5",
                 "--continuous-despot-trials", "3", "--backend", "serial", "--no-progress",
                 "--out", str(out)]) == 0
    keys = [json.loads(line)["key"] for line in
            (out / "trials.jsonl").read_text().splitlines()[1:]]
    assert sorted(k for k in keys if "lat-despot-continuous" in k) == [
        "right_obstacles/lat-despot-continuous/continuous/0",
        "right_obstacles/lat-despot-continuous/continuous/1"]
    entries = json.loads((out / "summary.json").read_text())["scenes"]["right_obstacles"]
    entry = entries["lat-despot-continuous"]
    assert entry["value_model"] == "continuous" and entries["lift-qmdp"]["value_model"] == \
        "discrete"
    assert entry["discounted_value"] == entry["continuous_discounted_value"]
    assert entry["infeasible_rate"] == 0.0 and entry["trials"] == 2
    assert len(entry["success_over_time"]) == 5


def test_stores_written_before_continuous_outside_stay_resumable(tmp_path):
    """A trials file whose header lacks ``continuous_outside`` (the stored studies ran the
    sentinel before the setting existed) resumes with the sentinel and is refused, naming
    the setting, with ``return``."""
    from dataclasses import replace

    from experiments.latdespot_scenes import SceneSettings, trial_store
    from experiments.latdespot_study import RelSettings

    rel, scenes = RelSettings(), SceneSettings()
    header = trial_store(rel, scenes, tmp_path, resume=False).header
    assert "continuous_outside" not in header["settings"]
    trial_store(rel, scenes, tmp_path, resume=True)
    with pytest.raises(ValueError, match="continuous_outside"):
        trial_store(replace(rel, continuous_outside="return"), scenes, tmp_path, resume=True)
