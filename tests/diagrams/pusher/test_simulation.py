"""The pusher-slider diagram: the estimator LeafSystem on fixed inputs, a short push
through the whole diagram, and the ``cmanip push`` commands."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from cmanip.cli import main
from diagrams.pusher.simulation import simulate_push
from diagrams.pusher.systems import FORCE_SAMPLE_SIZE, VisuoTactileEstimator
from estimation.pushing.noise import PushingNoise
from models.objects import ObjectSpec
from models.pusher.log import PushLog
from models.pusher.procedure import Stroke
from models.pusher.rig import PusherSliderRig

RECT1 = ObjectSpec.load("rect1")


def test_estimator_system_starts_at_the_camera_pose_and_holds_it():
    system = VisuoTactileEstimator(RECT1.footprint(), PushingNoise(), rod_radius_m=0.003125,
                                   contact_threshold_n=0.3)
    context = system.CreateDefaultContext()
    sample = np.zeros(FORCE_SAMPLE_SIZE)
    sample[1:5] = [-0.2, 0.02, -0.2, -0.02]  # rods far behind, no force
    system.GetInputPort("force_sample").FixValue(context, sample)
    system.GetInputPort("camera").FixValue(context, [0.0, 0.01, -0.02, 0.1, 1.0])
    estimate = system.GetOutputPort("estimate")
    assert np.all(np.isnan(estimate.Eval(context)))
    simulator = Simulator(system, context)
    simulator.AdvanceTo(0.1)
    np.testing.assert_allclose(estimate.Eval(context), [0.01, -0.02, 0.1], atol=1e-6)
    assert len(system.smoother(context).update_seconds) >= 9


def test_estimator_system_waits_for_a_camera_pose():
    system = VisuoTactileEstimator(RECT1.footprint(), PushingNoise(), rod_radius_m=0.003125,
                                   contact_threshold_n=0.3)
    context = system.CreateDefaultContext()
    system.GetInputPort("force_sample").FixValue(context, np.zeros(FORCE_SAMPLE_SIZE))
    system.GetInputPort("camera").FixValue(context, [0.0, np.nan, np.nan, np.nan, 0.0])
    Simulator(system, context).AdvanceTo(0.05)
    assert np.all(np.isnan(system.GetOutputPort("estimate").Eval(context)))


@pytest.fixture(scope="module")
def short_push():
    """One 3 cm two-rod push of rect1 with the estimator in the loop (a few seconds)."""
    return simulate_push(PusherSliderRig.load(), RECT1, [Stroke(0.0, distance_m=0.03)],
                         seed=1, estimator_noise=PushingNoise())


def test_a_push_moves_the_object_and_the_rods_feel_it(short_push):
    log = short_push.log
    assert log.t[0] == pytest.approx(0.0) and np.all(np.diff(log.t) > 0)
    moved = log.truth[-1] - log.truth[0]
    assert 0.02 < moved[0] < 0.04 and abs(moved[2]) < np.deg2rad(2)
    contacts = log.contacts()
    assert contacts[:, 0].any() and contacts[:, 1].any()
    touching = contacts.any(axis=1)
    # the rods push the object forward (+x) with about its sliding friction, 0.28 m g
    total = log.forces[touching].sum(axis=1)
    assert np.median(total[:, 0]) == pytest.approx(0.28 * 0.837 * 9.81, rel=0.3)
    assert log.vision_ok.sum() > 10


def test_the_in_loop_estimate_tracks_the_object(short_push):
    estimates = short_push.estimates
    started = np.all(np.isfinite(estimates[:, 1:]), axis=1)
    assert started.mean() > 0.9
    final = estimates[-1, 1:]
    truth = short_push.log.truth[-1]
    assert np.linalg.norm(final[:2] - truth[:2]) < 0.015
    assert len(short_push.update_ms) > 50


def test_cli_simulates_a_log_and_estimates_it(tmp_path, capsys):
    log_path = tmp_path / "push.csv"
    html = tmp_path / "replay.html"
    assert main(["push", "simulate", "--procedure", "random", "--strokes", "1", "--seed", "2",
                 "--object", "ellip2", "--out", str(log_path), "--html", str(html)]) == 0
    assert "meshcat" in html.read_text().lower()
    log = PushLog.read(log_path)
    assert log.object_name == "ellip2"
    estimates = tmp_path / "estimates.csv"
    assert main(["push", "estimate", str(log_path), "--history", "100",
                 "--out", str(estimates)]) == 0
    out = capsys.readouterr().out
    assert "RMSE against the log's ground truth" in out
    table = np.loadtxt(estimates, delimiter=",", skiprows=1)
    assert table.shape == (len(np.arange(log.t[0], log.t[-1] + 1e-9, 0.01)), 4)
    assert main(["push", "estimate", str(tmp_path / "missing.csv")]) == 2


def test_outlines_follow_the_estimate_and_hide_an_occluded_camera_pose():
    from pydrake.geometry import Meshcat

    from diagrams.pusher.systems import PoseOutlines

    meshcat = Meshcat()
    system = PoseOutlines(meshcat, RECT1.footprint(), height_m=0.015)
    context = system.CreateDefaultContext()
    estimate = system.GetInputPort("estimate")
    camera = system.GetInputPort("camera")
    estimate.FixValue(context, [0.1, 0.2, 0.3])
    camera.FixValue(context, [0.0, np.nan, np.nan, np.nan, 0.0])
    system.ForcedPublish(context)
    assert meshcat.HasPath("/pusher/estimate") and meshcat.HasPath("/pusher/camera")
    first = meshcat._GetPackedTransform("/pusher/estimate")
    hidden = meshcat._GetPackedProperty("/pusher/camera", "visible")
    estimate.FixValue(context, [0.2, 0.2, 0.3])
    camera.FixValue(context, [0.0, 0.0, 0.0, 0.0, 1.0])
    system.ForcedPublish(context)
    assert meshcat._GetPackedTransform("/pusher/estimate") != first
    assert meshcat._GetPackedProperty("/pusher/camera", "visible") != hidden
