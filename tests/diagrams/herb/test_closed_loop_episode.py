"""A short closed-loop episode in the whole HERB diagram, its outputs and the CLI."""

import json

import numpy as np
import pytest
from pydrake.geometry import Meshcat

from diagrams.belief_drawing import BeliefDrawer
from diagrams.herb.closed_loop import estimator_filter
from diagrams.herb.episode import run_episode
from diagrams.herb.report import write_episode
from diagrams.herb.settings import EpisodeSettings
from estimation.particles.belief import ParticleBelief
from planning.hand.precontact import PreContactSettings


@pytest.fixture(scope="module")
def meshcat():
    return Meshcat()


@pytest.fixture(scope="module")
def episode(small_hand_solution, meshcat):
    solution, _, _ = small_hand_solution
    settings = EpisodeSettings(object_name="small_box", policy="pomdp", estimator="cpf",
                               particles=60, horizon=3,
                               belief_mean=(0.30, 0.0, 0.0),
                               precontact=PreContactSettings(time_limit_s=2.0), seed=4)
    return run_episode(settings, solution, meshcat=meshcat, progress=False,
                       filter=estimator_filter("cpf", solution.model.world))


def test_episode_moves_the_hand_by_the_decided_actions(episode, small_hand_solution):
    solution, _, _ = small_hand_solution
    s = episode.summary
    assert s["stop_reason"] in ("horizon", "no_feasible_action")
    assert 1 <= s["steps"] <= 3 and s["infeasible_actions"] == 0
    vectors = solution.model.spec.action_vectors()
    index = {name: i for i, name in enumerate(solution.model.pomdp.actions)}
    commanded = sum(vectors[index[a]] for a in s["actions"])
    palm = episode.trace["palm"]
    moved = palm[-1] - palm[0]  # the hand faces world +x at the start
    np.testing.assert_allclose(moved[:2], commanded[:2], atol=2e-3)
    assert len(s["planning_ms"]) >= s["steps"] and s["planning_ms_median"] > 0


def test_the_object_starts_where_the_episode_drew_it(episode):
    s = episode.summary
    rel = np.array(s["initial_object_pose_hand"])
    # drawn from N((0.30, 0, 0), (5 cm, 5 cm, 15 deg)) and measured back from the plant
    assert abs(rel[0] - 0.30) < 0.25 and abs(rel[1]) < 0.25
    assert episode.trace["rmse_m"][0] > 0
    assert s["success"] == bool(episode.trace["in_goal"][-1])


def test_outputs_are_written_and_the_replay_shows_the_belief(episode, meshcat, tmp_path):
    write_episode(episode, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert {"success", "steps", "time_to_goal_s", "final_distance_to_goal_m",
            "estimator_rmse_over_time", "planning_ms"} <= set(summary)
    assert (tmp_path / "belief.png").stat().st_size > 10_000
    data = np.load(tmp_path / "trace.npz")
    decisions = len(summary["planning_ms"])
    assert data["decision_particles"].shape == (decisions, 60, 3)
    assert data["decision_true_rel"].shape == (decisions, 3)
    assert len(data["trace_time_s"]) == len(data["trace_rmse_m"]) > decisions
    html = (tmp_path / "replay.html").read_text()
    assert "<html" in html.lower() and "animation" in html.lower()
    for path in ("/belief/particles/0", "/belief/mean", "/belief/goal", "/belief/sensors/1/on"):
        assert meshcat.HasPath(path)


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="policy"):
        EpisodeSettings(policy="greedy")
    with pytest.raises(ValueError, match="estimator"):
        EpisodeSettings(estimator="ukf")
    with pytest.raises(ValueError, match="lat_despot_model"):
        EpisodeSettings(lat_despot_model="exact")
    with pytest.raises(ValueError, match="lat_despot_outside"):
        EpisodeSettings(lat_despot_outside="wrap")
    with pytest.raises(ValueError, match="needs lat_despot_model 'continuous'"):
        EpisodeSettings(lat_despot_outside="return")
    assert EpisodeSettings(lat_despot_model="continuous",
                           lat_despot_outside="return").lat_despot_outside == "return"
    with pytest.raises(ValueError, match="lat_despot_trials"):
        EpisodeSettings(lat_despot_trials=0)


def test_drawer_draws_particles_mean_goal_and_sensors(meshcat):
    belief = ParticleBelief.uniform(np.array([[0.2, 0.0, 0.0], [0.25, 0.01, 0.1]]))
    drawer = BeliefDrawer(meshcat, np.array([[-0.01, -0.01], [0.01, -0.01], [0.01, 0.01]]),
                          np.array([[0.1, -0.04], [0.14, 0.04]]),
                          np.array([[0.1, -0.03], [0.1, 0.03]]), belief, height_m=0.74,
                          object_rgba=(0.2, 0.6, 0.3, 1.0), particles=2)
    context = drawer.CreateDefaultContext()
    drawer.GetInputPort("belief").FixValue(context, belief)
    drawer.GetInputPort("palm_pose").FixValue(context, np.zeros(3))
    drawer.GetInputPort("sensor_contact").FixValue(context, np.array([1.0, 0.0]))
    drawer.ForcedPublish(context)
    for path in ("/belief/particles/1", "/belief/mean", "/belief/goal",
                 "/belief/sensors/0/on", "/belief/sensors/1/off"):
        assert meshcat.HasPath(path)


def test_an_episode_refuses_an_object_the_model_was_not_built_for(small_hand_solution):
    solution, _, _ = small_hand_solution
    with pytest.raises(ValueError, match="planning model is for 'small_box'"):
        run_episode(EpisodeSettings(object_name="bottle"), solution, progress=False)


def test_run_command_rejects_bad_settings_before_any_work(tmp_path, capsys):
    from cmanip.cli import main

    assert main(["run", "--particles", "2", "--out", str(tmp_path)]) == 2
    assert "particles must be >= 10" in capsys.readouterr().err
    assert main(["experiment", "closedloop", "--trials", "0", "--out", str(tmp_path)]) == 2
    assert "trials must be >= 1" in capsys.readouterr().err


def test_the_goal_is_never_drawn_in_the_object_colour():
    from diagrams.belief_drawing import goal_rgba

    for rgba in ((0.2, 0.6, 0.3, 1.0), (0.8, 0.15, 0.75, 1.0), (0.1, 0.6, 0.9, 1.0)):
        goal = goal_rgba(rgba)
        distance = np.linalg.norm(np.array([goal.r(), goal.g(), goal.b()]) - rgba[:3])
        assert distance > 0.5


def test_a_failed_episode_has_no_time_to_goal_and_a_box_is_not_symmetric(episode):
    summary = episode.summary
    assert summary["object_rotationally_symmetric"] is False
    assert not summary["success"]  # three steps from 30 cm cannot reach the goal
    assert summary["time_to_goal_s"] is None


def test_a_bottle_is_rotationally_symmetric():
    from models.objects import ObjectSpec

    assert ObjectSpec.load("bottle").rotationally_symmetric
    assert not ObjectSpec.load("small_box").rotationally_symmetric


def test_a_lat_despot_episode_runs_the_lattice_edges_it_planned(small_hand_solution, meshcat,
                                                                 tmp_path):
    solution, _, _ = small_hand_solution
    settings = EpisodeSettings(object_name="small_box", planner="lat-despot",
                               lat_despot_trials=3, estimator="cpf", particles=60, horizon=2,
                               belief_mean=(0.20, 0.0, 0.0), seed=4)
    episode = run_episode(settings, solution, meshcat=meshcat, progress=False,
                          filter=estimator_filter("cpf", solution.model.world),
                          cache_dir=tmp_path)
    s = episode.summary
    assert s["steps"] >= 1 and s["infeasible_actions"] == 0
    lattice = s["lattice"]
    assert 0 < lattice["edges_evaluated"] <= lattice["edges"]
    assert len(lattice["executed_clearance_m"]) == s["steps"]
    assert lattice["executed_clearance_min_m"] > 0  # Drake's signed distance, in free space
    vectors = solution.model.spec.action_vectors()
    index = {name: i for i, name in enumerate(solution.model.pomdp.actions)}
    commanded = sum(vectors[index[a]] for a in s["actions"])
    palm = episode.trace["palm"]
    np.testing.assert_allclose((palm[-1] - palm[0])[:2], commanded[:2], atol=2e-3)
    assert meshcat.HasPath("/lattice/feasible/0") and meshcat.HasPath("/lattice/chosen/0")
    assert list((tmp_path / "lattice").glob("*.npz"))  # the IK table was cached


def test_the_true_object_never_starts_inside_the_clutter():
    """cul_de_sac's clutter lies where the thesis' beliefs put some objects: the start is
    drawn again until it is free, and a belief entirely in the clutter is a clear error."""
    import numpy as np
    import pytest

    from models.herb.scene import SceneSpec
    from models.planar.world import PlanarWorld
    from planning.lattice.contact import UnmodelledContact

    scene = SceneSpec.load("cul_de_sac", object_override="bottle")
    world = PlanarWorld.load("bottle", sensors="fingertips")
    contact = UnmodelledContact(scene)
    palm = scene.hand_start.as_array()[None]
    mean, std = np.array([0.35, 0.0, 0.0]), np.array([0.05, 0.05, 0.26])
    draws = world.sample_gaussian(mean, std, 400, rng=np.random.default_rng(0))
    assert contact.touches(np.repeat(palm, 400, axis=0), draws).any()  # some would
    rng = np.random.default_rng(1)
    starts = np.array([contact.free_start(lambda n: world.sample_gaussian(mean, std, n,
                                                                          rng=rng))
                       for _ in range(40)])
    assert not contact.touches(np.repeat(palm, 40, axis=0), starts).any()
    rng = np.random.default_rng(1)
    many = contact.free_starts(lambda n: world.sample_gaussian(mean, std, n, rng=rng), 300,
                               batch=300)  # a particle belief conditioned the same way
    assert many.shape == (300, 3)
    assert not contact.touches(np.repeat(palm, 300, axis=0), many).any()
    with pytest.raises(ValueError, match="clutter"):
        far = np.random.default_rng(2)
        contact.free_start(lambda n: world.sample_gaussian(np.array([0.0, 5.0, 0.0]),
                                                           np.full(3, 1e-4), n, rng=far))
