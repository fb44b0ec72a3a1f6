"""Short simulations of the whole HERB diagram: smoke test and the tactile side test."""

import dataclasses
import json

import numpy as np
import pytest
from pydrake.geometry import Meshcat

from cmanip.cli import main
from diagrams.herb.straight_push import InfeasiblePush, run_straight_push, write_outputs
from models.herb.scene import PlanarPose, SceneSpec
from models.herb.tactile import TactileLayout, TactileNoise

LAYOUT = TactileLayout.load("default")
F3_SIDE = {"f3_tip", "f3_distal_0", "f3_proximal_0", "palm_2"}
F1_F2_SIDE = {"f1_tip", "f1_distal_0", "f1_proximal_0", "f2_tip", "f2_distal_0",
              "f2_proximal_0", "palm_0"}


def offset_scene(lateral_m: float, object_name: str = "bottle") -> SceneSpec:
    """The empty scene with the object shifted sideways relative to the hand (+ = F3 side)."""
    scene = SceneSpec.load("empty", object_override=object_name)
    hand = scene.hand_start
    return dataclasses.replace(scene, object_pose=PlanarPose(hand.x + 0.15, hand.y + lateral_m,
                                                             0.0))


@pytest.mark.parametrize("lateral_m,side,other", [(0.05, F3_SIDE, F1_F2_SIDE),
                                                  (-0.05, F1_F2_SIDE, F3_SIDE)])
def test_offset_push_lights_only_that_side(lateral_m, side, other):
    outcome = run_straight_push(offset_scene(lateral_m), 0.12, layout=LAYOUT,
                                noise=TactileNoise.noiseless(), progress=False)
    fired = {name for name, count in outcome.summary["contact_counts"].items() if count}
    assert fired, "the push never touched the object"
    assert fired <= side, f"patches off the object's side fired: {fired - side}"
    assert not fired & other
    assert outcome.summary["object_displacement_m"] > 0.02


def test_short_push_smoke(tmp_path):
    meshcat = Meshcat()
    outcome = run_straight_push(SceneSpec.load("empty"), 0.08, layout=LAYOUT,
                                meshcat=meshcat, progress=False)
    write_outputs(outcome, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in ("sim_time_s", "wall_time_s", "real_time_factor", "object_displacement_m"):
        assert np.isfinite(summary[key])
    assert set(summary["contact_counts"]) == set(LAYOUT.patch_names)
    assert summary["palm_final_error_m"] < 0.002
    assert (tmp_path / "tactile.png").stat().st_size > 10_000
    html = (tmp_path / "replay.html").read_text()
    assert "<html" in html.lower() and "animation" in html.lower()


def test_infeasible_push_is_reported():
    with pytest.raises(InfeasiblePush, match="pose"):
        run_straight_push(SceneSpec.load("empty"), 0.9, layout=LAYOUT, progress=False)


def test_cli_reports_bad_scene(tmp_path, capsys):
    assert main(["simulate", "--scene", "kitchen", "--out", str(tmp_path)]) == 2
    assert "unknown scenes name" in capsys.readouterr().err


@pytest.mark.parametrize("flag,value,message", [
    ("--push-distance", "-0.1", "--push-distance -0.1 m is outside"),
    ("--hand-speed", "5", "--hand-speed 5.0 m/s is outside"),
    ("--time-step", "1.0", "time_step_s=1.0 is outside"),
    ("--tactile", "braille", "unknown tactile name"),
])
def test_cli_reports_bad_options(tmp_path, capsys, flag, value, message):
    assert main(["simulate", flag, value, "--out", str(tmp_path), "--no-progress"]) == 2
    assert message in capsys.readouterr().err
