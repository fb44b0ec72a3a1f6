"""Loading scenes and objects: by name, by path, and clear errors for malformed files."""

import textwrap

import numpy as np
import pytest

from models.config import ConfigError
from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout
from models.objects import ObjectSpec

GOOD_SCENE = textwrap.dedent("""\
    arm: right
    table: {top_height_m: 0.735, size_m: [0.74, 1.85], center_xy_m: [0.9, 0.0],
            thickness_m: 0.04}
    object:
      name: box
      pose: {x_m: 0.84, y_m: -0.25, theta_deg: 0}
    hand:
      height_above_table_m: 0.06
      start: {x_m: 0.68, y_m: -0.25, theta_deg: 0}
    """)


@pytest.mark.parametrize("name", ["empty", "right_obstacles", "left_obstacles", "cul_de_sac"])
def test_builtin_scenes_load(name):
    scene = SceneSpec.load(name)
    assert scene.name == name
    assert scene.table.contains(scene.object_pose.x, scene.object_pose.y)


def test_cul_de_sac_adds_a_box_to_the_right_obstacles():
    right = {o.spec.name for o in SceneSpec.load("right_obstacles").obstacles}
    dead_end = {o.spec.name for o in SceneSpec.load("cul_de_sac").obstacles}
    assert right < dead_end and len(dead_end - right) == 1


def test_scene_by_path_with_object_override(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(GOOD_SCENE)
    scene = SceneSpec.load(path, object_override="bottle")
    assert scene.name == "mine" and scene.object.shape == "cylinder"


def write(tmp_path, text):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("mutation,field,message", [
    (("height_above_table_m: 0.06", "height_above_table_m: high"), "hand.height_above_table_m",
     "expected a number"),
    (("arm: right", "arm: middle"), "arm", "not one of right, left"),
    (("theta_deg: 0}\nhand", "theta_deg: 0, z_m: 1}\nhand"), "object.pose.z_m", "unknown field"),
    (("size_m: [0.74, 1.85]", "size_m: [0.74]"), "table.size_m", "list of 2 numbers"),
    (("top_height_m: 0.735", "top_height_m: -1"), "table.top_height_m", "outside the allowed"),
    (("x_m: 0.84", "x_m: 3.0"), "object.pose", "not on the table"),
    (("name: box", "name: teapot"), "", "unknown objects name"),
])
def test_malformed_scene_names_file_and_field(tmp_path, mutation, field, message):
    path = write(tmp_path, GOOD_SCENE.replace(*mutation, 1))
    with pytest.raises(ConfigError) as err:
        SceneSpec.load(path)
    assert message in str(err.value)
    if field:
        assert str(path) in str(err.value) and f"'{field}'" in str(err.value)


def test_missing_required_field(tmp_path):
    path = write(tmp_path, GOOD_SCENE.replace("hand:", "hands:"))
    with pytest.raises(ConfigError, match="field 'hand': required field is missing"):
        SceneSpec.load(path)


@pytest.mark.parametrize("mutation,field", ids=["thickness", "object_theta", "hand_theta"],
                         argvalues=[
    (("center_xy_m: [0.9, 0.0],\n        thickness_m: 0.04}", "center_xy_m: [0.9, 0.0]}"),
     "table.thickness_m"),
    (("x_m: 0.84, y_m: -0.25, theta_deg: 0}", "x_m: 0.84, y_m: -0.25}"), "object.pose.theta_deg"),
    (("x_m: 0.68, y_m: -0.25, theta_deg: 0}", "x_m: 0.68, y_m: -0.25}"), "hand.start.theta_deg"),
])
def test_scene_physical_fields_are_required(tmp_path, mutation, field):
    text = GOOD_SCENE.replace(*mutation, 1)
    assert text != GOOD_SCENE
    path = write(tmp_path, text)
    with pytest.raises(ConfigError, match=f"field '{field}': required field is missing") as err:
        SceneSpec.load(path)
    assert str(path) in str(err.value)


def test_obstacles_may_omit_their_mass(tmp_path):
    """Obstacles are welded: their mass never enters the dynamics (documented default)."""
    path = write(tmp_path, GOOD_SCENE + textwrap.dedent("""\
        obstacles:
          - {name: can, shape: cylinder, radius_m: 0.03, height_m: 0.1,
             pose: {x_m: 0.9, y_m: 0.2, theta_deg: 0}}
        """))
    assert SceneSpec.load(path).obstacles[0].spec.mass_kg == 1.0


def test_not_yaml_and_not_a_mapping(tmp_path):
    with pytest.raises(ConfigError, match="not valid YAML"):
        SceneSpec.load(write(tmp_path, "arm: [right\n"))
    with pytest.raises(ConfigError, match="expected a mapping"):
        SceneSpec.load(write(tmp_path, "- just\n- a list\n"))


def test_unknown_scene_name_lists_builtins():
    with pytest.raises(ConfigError, match="built-in: closed_loop, configest_boxes, "
                                          "cul_de_sac, empty, left_obstacles"):
        SceneSpec.load("kitchen")


@pytest.mark.parametrize("name,shape", [("box", "box"), ("bottle", "cylinder"),
                                        ("rect1", "box"), ("ellip2", "polygon"),
                                        ("butter", "polygon")])
def test_builtin_objects(name, shape):
    spec = ObjectSpec.load(name)
    assert spec.shape == shape
    footprint = spec.footprint()
    # Counter-clockwise, centred footprints.
    x, y = footprint[:, 0], footprint[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0
    assert abs(footprint.mean(axis=0)).max() < 1e-9 or shape == "polygon"


def test_ellip2_area_close_to_the_ellipse():
    footprint = ObjectSpec.load("ellip2").footprint()
    x, y = footprint[:, 0], footprint[:, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert area == pytest.approx(np.pi * 0.105 / 2 * 0.1309 / 2, rel=0.01)


def test_user_polygon_object_is_recentred(tmp_path):
    path = tmp_path / "wedge.yaml"
    path.write_text("shape: polygon\nvertices_m: [[0, 0], [0.1, 0], [0, 0.1]]\n"
                    "height_m: 0.05\nmass_kg: 0.2\n")
    spec = ObjectSpec.load(path)
    np.testing.assert_allclose(np.mean(spec.footprint(), axis=0), 0.0, atol=1e-12)


def test_non_convex_polygon_rejected(refused):
    refused(ObjectSpec.load, "shape: polygon\nvertices_m: [[0, 0], [0.1, 0], [0.02, 0.02], "
                             "[0, 0.1]]\nheight_m: 0.05\nmass_kg: 0.2\n",
            "'vertices_m': the polygon must be convex")


def test_tactile_layout_errors(refused):
    refused(TactileLayout.load, "fingers: [f1, f4]\n", "'fingers'")
    refused(TactileLayout.load, "palm_strips: 2.5\n", "'palm_strips': expected an integer")


OBJECT = "shape: box\nsize_m: [0.05, 0.1]\nheight_m: 0.12\nmass_kg: 0.3\n"


@pytest.mark.parametrize("text,field", ids=["mass", "segments"], argvalues=[
    (OBJECT.replace("mass_kg: 0.3\n", ""), "mass_kg"),
    ("shape: ellipse\naxes_m: [0.1, 0.13]\nheight_m: 0.013\nmass_kg: 1.1\n", "segments"),
])
def test_object_physical_fields_are_required(refused, text, field):
    refused(ObjectSpec.load, text, f"field '{field}': required field is missing")


def test_contact_overrides_give_both_friction_coefficients(tmp_path, refused):
    refused(ObjectSpec.load, OBJECT + "contact: {mu_dynamic: 0.6}\n",
            "'contact.mu_static': required")
    refused(ObjectSpec.load, OBJECT + "contact: {mu_static: 0.6}\n",
            "'contact.mu_dynamic': required")
    path = tmp_path / "thing.yaml"
    path.write_text(OBJECT + "contact: {mu_static: 0.6, mu_dynamic: 0.5}\n")
    material = ObjectSpec.load(path).material
    assert (material.mu_static, material.mu_dynamic) == (0.6, 0.5)


def test_contact_modulus_with_rigid_is_a_contradiction(tmp_path, refused):
    refused(ObjectSpec.load, OBJECT + "contact: {rigid: true, hydroelastic_modulus_pa: 1.0e+7}\n",
            "'contact.hydroelastic_modulus_pa'")
    path = tmp_path / "thing.yaml"
    path.write_text(OBJECT + "contact: {rigid: true}\n")
    assert ObjectSpec.load(path).material.hydroelastic_modulus_pa is None


def test_contact_overrides_keep_a_rigid_default_rigid():
    from models.config import Fields
    from models.contact import TABLE_MATERIAL, ContactMaterial

    material = ContactMaterial.from_fields(
        Fields({"mu_static": 0.2, "mu_dynamic": 0.2}, "table.yaml", "contact"), TABLE_MATERIAL)
    assert material.hydroelastic_modulus_pa is None
    with pytest.raises(ConfigError, match="'contact.hydroelastic_modulus_pa': required"):
        ContactMaterial.from_fields(Fields({"rigid": False}, "table.yaml", "contact"),
                                    TABLE_MATERIAL)


@pytest.mark.parametrize("name", ["box", "bottle", "rect1", "ellip2", "butter", "small_box"])
def test_builtin_objects_keep_their_numbers(name):
    """The built-in files give every physical field; these are the values they had."""
    expected = {"box": 0.3, "bottle": 0.4, "rect1": 0.837, "ellip2": 1.110, "butter": 1.197,
                "small_box": 0.15}
    spec = ObjectSpec.load(name)
    assert spec.mass_kg == expected[name]
    if name == "ellip2":
        assert len(spec.vertices_m) == 48


@pytest.mark.parametrize("text,line,column", ids=["flow", "indent", "character"], argvalues=[
    ("arm: right\ntable: [1, 2\n", 3, 1),
    ("arm: right\nhand:\n  a: 1\n   b: 2\n", 4, 5),
    ("arm: right\nname: \"a\x07\"\n", 2, 9),
])
def test_yaml_syntax_error_names_the_file_line_and_column(tmp_path, text, line, column):
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        SceneSpec.load(path)
    message = str(err.value)
    assert message.startswith(f"{path}: not valid YAML: line {line}, column {column}: ")
    assert "<unicode string>" not in message


def test_file_that_is_not_utf8_names_the_file(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_bytes(GOOD_SCENE.replace("right", "r\xe9ght").encode("latin-1"))
    with pytest.raises(ConfigError, match="not UTF-8 text: byte 0xe9 at line 1, column 7") as err:
        SceneSpec.load(path)
    assert str(err.value).startswith(f"{path}: ")
