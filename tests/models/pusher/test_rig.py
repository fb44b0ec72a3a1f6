"""Seed 003's rig: its data file, friction combination, procedures, camera occlusion,
the log format and the object's support mesh."""

import numpy as np
import pytest

from models.config import ConfigError
from models.objects import ObjectSpec
from models.pusher.log import LogFormatError, PushLog
from models.pusher.occlusion import (
    segments_hit_box,
    segments_hit_vertical_cylinder,
    tag_corners,
    tag_visible,
)
from models.pusher.procedure import Stroke, random_procedure, standard_procedure, stroke_waypoints
from models.pusher.rig import DEFAULT_RIG, PusherSliderRig, mu_completing_pair, occluders

RECT1 = ObjectSpec.load("rect1").footprint()


def test_rig_file_loads_with_the_papers_numbers():
    rig = PusherSliderRig.load()
    assert rig.pusher_diameter_m == pytest.approx(0.00625)
    assert rig.surfaces == {"abs": 0.16, "delrin": 0.15, "plywood": 0.28, "polyurethane": 0.35}
    assert rig.surface_mu == 0.28
    assert rig.with_surface("abs").surface_mu == 0.16
    with pytest.raises(ValueError, match="unknown surface 'ice'"):
        rig.with_surface("ice")


def test_rig_file_errors_name_the_field(tmp_path):
    good = DEFAULT_RIG.read_text()
    bad = tmp_path / "rig.yaml"
    bad.write_text(good.replace("surface: plywood", "surface: steel"))
    with pytest.raises(ConfigError, match="field 'surface'"):
        PusherSliderRig.load(bad)
    bad.write_text(good.replace("rate_hz: 30 ", "rate_hz: -1 "))
    with pytest.raises(ConfigError, match="camera.rate_hz"):
        PusherSliderRig.load(bad)
    bad.write_text(good.replace("pusher_diameter_m:", "pusher_diameter:"))
    with pytest.raises(ConfigError, match="pusher_diameter"):
        PusherSliderRig.load(bad)


@pytest.mark.parametrize("line,field", [
    ("pusher_diameter_m:", "pusher_diameter_m"),
    ("pusher_spacing_m:", "pusher_spacing_m"),
    ("pusher_object_mu:", "pusher_object_mu"),
    ("push_speed_m_per_s:", "push_speed_m_per_s"),
    ("surface: plywood", "surface"),
    ("  noise_n:", "force_sensor.noise_n"),
    ("  position_noise_m:", "force_sensor.position_noise_m"),
    ("  position_m:", "camera.position_m"),
    ("  noise_deg:", "camera.noise_deg"),
    ("wrist_size_m:", "wrist_size_m"),
])
def test_rig_file_physical_fields_are_required(tmp_path, line, field):
    """A rig file missing a number is an error, not the built-in rig's value."""
    kept = [text for text in DEFAULT_RIG.read_text().splitlines()
            if not text.startswith(line)]
    bad = tmp_path / "rig.yaml"
    bad.write_text("\n".join(kept) + "\n")
    with pytest.raises(ConfigError, match=f"field '{field}': required field is missing") as err:
        PusherSliderRig.load(bad)
    assert str(bad) in str(err.value)


def test_rig_file_without_a_sensor_section_is_an_error(tmp_path):
    text = DEFAULT_RIG.read_text()
    bad = tmp_path / "rig.yaml"
    bad.write_text(text[:text.index("force_sensor:")] + text[text.index("camera:"):])
    with pytest.raises(ConfigError, match="field 'force_sensor': required field is missing"):
        PusherSliderRig.load(bad)


def test_built_in_rig_file_matches_the_documented_defaults():
    """The loader no longer falls back on the dataclass defaults; they stay the file's."""
    assert PusherSliderRig.load() == PusherSliderRig(source=str(DEFAULT_RIG))


@pytest.mark.parametrize("pair", [0.15, 0.25, 0.35, 0.45])
def test_table_friction_combines_to_the_pair_coefficient(pair):
    mu_t = mu_completing_pair(pair, 0.25)
    assert 2 * mu_t * 0.25 / (mu_t + 0.25) == pytest.approx(pair)


def test_impossible_pair_friction_is_refused():
    with pytest.raises(ValueError, match="above 0.3"):
        mu_completing_pair(0.6, 0.25)


def test_stroke_starts_behind_the_object_and_pushes_through_it():
    pose = np.array([0.1, 0.2, 0.3])
    radius, spacing = 0.003125, 0.04
    durations, poses = stroke_waypoints(Stroke(0.0, distance_m=0.05), pose, RECT1,
                                        np.array([-0.3, 0.2, 0.0]), spacing_m=spacing,
                                        rod_radius_m=radius, push_speed=0.06,
                                        transit_speed=0.09)
    assert np.all(durations > 0)
    c, s = np.cos(0.3), np.sin(0.3)
    to_object = np.array([[c, s], [-s, c]])  # world -> object frame
    start, end = poses[-3], poses[-2]
    start_local = to_object @ (start[:2] - pose[:2])
    end_local = to_object @ (end[:2] - pose[:2])
    assert start_local[0] == pytest.approx(-0.045 - radius - 0.02)
    assert start_local[1] == pytest.approx(0.0, abs=1e-12)
    assert end_local[0] - start_local[0] == pytest.approx(0.07)
    assert start[2] == pytest.approx(0.3) and end[2] == pytest.approx(0.3)
    # a push takes distance / push speed
    assert durations[-2] == pytest.approx(0.07 / 0.06)


def test_one_finger_stroke_keeps_the_other_rod_off_the_object():
    pose = np.zeros(3)
    _, poses = stroke_waypoints(Stroke(0.0, lateral_m=0.025, fingers="one"), pose, RECT1,
                                np.array([-0.3, 0.0, 0.0]), spacing_m=0.04,
                                rod_radius_m=0.003125, push_speed=0.06, transit_speed=0.09)
    start = poses[-3]
    rods_y = start[1] + np.array([0.02, -0.02])
    assert np.any(np.isclose(rods_y, 0.025))
    assert np.any(np.abs(rods_y) > 0.045 + 0.003125)


def test_procedures():
    assert len(standard_procedure()) == 8
    a = random_procedure(np.random.default_rng(4), 5)
    assert a == random_procedure(np.random.default_rng(4), 5)
    with pytest.raises(ValueError, match="fingers"):
        Stroke(0.0, fingers="three")


def test_segment_against_vertical_cylinder():
    start = np.array([0.0, -1.0, 0.05])
    ends = np.array([[0.0, 1.0, 0.05], [0.1, 1.0, 0.05], [0.0, 1.0, 0.5]])
    hit = segments_hit_vertical_cylinder(start, ends, np.zeros(2), 0.01, (0.0, 0.1))
    # straight through the axis; 5 cm to the side at the axis; rising above the rod's top
    np.testing.assert_array_equal(hit, [True, False, False])


def test_segment_against_rotated_box():
    start = np.array([-1.0, 0.0, 0.0])
    ends = np.array([[1.0, 0.0, 0.0], [1.0, 0.3, 0.0]])
    hit = segments_hit_box(start, ends, np.zeros(3), np.pi / 4, np.array([0.1, 0.1, 0.1]))
    np.testing.assert_array_equal(hit, [True, False])


def test_the_carriage_hides_the_tag_only_when_between_camera_and_object():
    rig = PusherSliderRig.load()
    cylinders, boxes = occluders(rig)
    corners = tag_corners(np.zeros(3), rig.camera.tag_size_m, 0.013)
    camera = np.array(rig.camera.position_m)
    towards_camera = camera[:2] / np.linalg.norm(camera[:2])
    between = np.array([*(0.12 * towards_camera), 0.0])
    away = np.array([*(-0.3 * towards_camera), 0.0])
    assert not tag_visible(camera, corners, between, cylinders, boxes, 0.002)
    assert tag_visible(camera, corners, away, cylinders, boxes, 0.002)


def test_log_round_trip(tmp_path, synthetic_push_log):
    path = tmp_path / "log.csv"
    synthetic_push_log.write(path)
    back = PushLog.read(path)
    np.testing.assert_allclose(back.forces, synthetic_push_log.forces, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(back.truth, synthetic_push_log.truth, rtol=1e-8, atol=1e-12)
    np.testing.assert_array_equal(back.vision_ok, synthetic_push_log.vision_ok)
    assert back.object_name == "rect1" and back.contact_threshold_n == 0.3


def test_malformed_logs_are_reported_with_file_and_line(tmp_path, synthetic_push_log):
    path = tmp_path / "log.csv"
    synthetic_push_log.write(path)
    lines = path.read_text().splitlines()
    (tmp_path / "magic.csv").write_text("\n".join(["# something else"] + lines[1:]))
    with pytest.raises(LogFormatError, match="magic.csv:1"):
        PushLog.read(tmp_path / "magic.csv")
    header = next(i for i, line in enumerate(lines) if line.startswith("t_s"))
    dropped = lines[:header] + [lines[header].replace("rod1_fx_n", "rod1_fz_n")] + lines[header
                                                                                       + 1:]
    (tmp_path / "column.csv").write_text("\n".join(dropped))
    with pytest.raises(LogFormatError, match="rod1_fx_n"):
        PushLog.read(tmp_path / "column.csv")
    swapped = lines[:header + 1] + [lines[header + 2], lines[header + 1]] + lines[header + 3:]
    (tmp_path / "time.csv").write_text("\n".join(swapped))
    with pytest.raises(LogFormatError, match="t_s must increase"):
        PushLog.read(tmp_path / "time.csv")
    with pytest.raises(LogFormatError, match="no such log"):
        PushLog.read(tmp_path / "missing.csv")


def test_bad_data_rows_are_reported_with_the_editors_line_number(tmp_path, synthetic_push_log):
    """Line numbers are 1-based and count every line of the file, the header included."""
    path = tmp_path / "log.csv"
    synthetic_push_log.write(path)
    lines = path.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("t_s"))
    k = header + 5  # the fifth data row: line k + 1 of the file
    values = lines[k].split(",")

    def read_with(row: str) -> str:
        bad = tmp_path / "bad.csv"
        bad.write_text("\n".join(lines[:k] + [row] + lines[k + 1:]) + "\n")
        with pytest.raises(LogFormatError) as err:
            PushLog.read(bad)
        return str(err.value)

    message = read_with(",".join(values[:3] + ["abc"] + values[4:]))
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 1}: ")
    assert "'abc'" in message and "rod0_fx_n" in message
    message = read_with(",".join(values[:3] + ["1_0"] + values[4:]))  # float() would take it
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 1}: column rod0_fx_n: '1_0'")
    message = read_with(",".join(values[:-1]))
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 1}: ")
    assert f"{len(values) - 1} values" in message
    message = read_with(",".join(["nan"] + values[1:]))
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 1}: ")
    message = read_with(",".join(["-1"] + values[1:]))  # time goes back at this row
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 1}: column t_s must increase")
    # Comment and blank lines between the rows count as lines (np.loadtxt skips them).
    message = read_with("# a note\n\n" + ",".join(values[:3] + ["abc"] + values[4:]))
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 3}: ")
    message = read_with("# a note\n\n" + ",".join(["nan"] + values[1:]))
    assert message.startswith(f"{tmp_path / 'bad.csv'}:{k + 3}: column t_s must be finite")


def test_non_utf8_log_is_a_format_error(tmp_path, synthetic_push_log):
    path = tmp_path / "log.csv"
    synthetic_push_log.write(path)
    path.write_bytes(path.read_bytes().replace(b"rect1", b"r\xe9ct1"))
    with pytest.raises(LogFormatError, match=r"log.csv:2: not UTF-8 text"):
        PushLog.read(path)


def test_support_mesh_gives_a_contact_surface_of_many_polygons():
    """The tessellated bottom face is what distributes the frictional moment (see
    models.bodies.tessellated_prism_mesh)."""
    from pydrake.geometry import HydroelasticContactRepresentation
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
    from pydrake.systems.framework import DiagramBuilder

    from models.pusher.rig import add_pusher_slider

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=0.002, contact_model="hydroelastic_with_fallback"), builder)
    world = add_pusher_slider(plant, PusherSliderRig.load(), ObjectSpec.load("rect1"))
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.SetPositions(plant_context, world.carriage, [-0.3, 0.0, 0.0])  # rods far away
    X = world.X_WO_initial(np.zeros(3))
    plant.SetFreeBodyPose(plant_context, world.object_body,
                          RigidTransform(X.rotation(), X.translation() - [0, 0, 1e-4]))
    query = scene_graph.get_query_output_port().Eval(
        scene_graph.GetMyContextFromRoot(context))
    surfaces = query.ComputeContactSurfaces(HydroelasticContactRepresentation.kPolygon)
    assert len(surfaces) == 1
    assert surfaces[0].num_faces() >= 20
