"""The BarrettHand model: frames, masses, couplings, patches."""

import numpy as np
import pytest
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.framework import DiagramBuilder

from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout
from models.herb.world import populate_world


def build(layout_name="default"):
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(time_step=0.005,
                                           discrete_contact_approximation="lagged"), builder)
    world = populate_world(plant, scene_graph, SceneSpec.load("empty"),
                           layout=TactileLayout.load(layout_name))
    plant.Finalize()
    return plant, world


@pytest.fixture(scope="module")
def herb():
    return build()


def test_palm_is_0151_m_past_the_wrist_centre_along_the_flange_axis(herb):
    plant, world = herb
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = world.robot_positions(plant, rng.uniform(-1, 1, 7))
        plant.SetPositions(context, q)
        X_W6 = plant.GetFrameByName("wam6", world.wam).CalcPoseInWorld(context)
        X_W7 = plant.GetFrameByName("wam7", world.wam).CalcPoseInWorld(context)
        X_WP = world.hand.palm_frame.CalcPoseInWorld(context)
        # Wrist centre (DH frame 6 origin) -> palm: 0.06 + 0.012 + 0.079 m along z7.
        offset = X_WP.translation() - X_W6.translation()
        np.testing.assert_allclose(offset, 0.151 * X_W7.rotation().col(2), atol=1e-12)
        # The palm's z is the flange's z (out of the palm).
        np.testing.assert_allclose(X_WP.rotation().matrix(), X_W7.rotation().matrix(), atol=1e-12)


def test_hand_mass_matches_reference(herb):
    plant, world = herb
    bodies = [plant.get_body(i) for i in plant.GetBodyIndices(world.hand.instance)]
    total = sum(b.default_mass() for b in bodies)
    # palm 0.609 + F/T 0.133 + 2 knuckles 0.141 + 3 proximal 0.062 + 3 distal 0.042
    assert total == pytest.approx(0.609 + 0.133 + 2 * 0.141 + 3 * 0.062 + 3 * 0.042)


def test_couplings_and_actuators(herb):
    plant, world = herb
    # F2 spread follows F1; each distal follows its proximal.
    assert plant.num_constraints() == 4
    names = [a.name() for a in world.hand.actuators]
    assert names == ["bh_spread", "bh_f1_proximal", "bh_f2_proximal", "bh_f3_proximal"]
    assert all(a.has_controller() for a in world.hand.actuators)
    arm = [plant.GetJointActuatorByName(f"wam_j{k}", world.wam) for k in range(1, 8)]
    assert all(a.has_controller() for a in arm)


@pytest.mark.parametrize("layout_name,expected", [
    ("fingertips", 3), ("default", 3 * 3 + 3), ("dense", 3 * (1 + 3 + 4) + 8),
    ("distal_links", 3 * 3)])
def test_patch_geometry_follows_the_layout(layout_name, expected):
    plant, world = build(layout_name)
    layout = TactileLayout.load(layout_name)
    assert len(layout.patch_names) == expected
    assert set(world.hand.patch_geometry) == set(layout.patch_names)
    assert len(set(world.hand.patch_geometry.values())) == expected


def test_palm_frame_sits_on_the_palm_surface(herb):
    plant, world = herb
    context = plant.CreateDefaultContext()
    X_BP = world.hand.palm_frame.CalcPose(context, world.hand.base.body_frame())
    np.testing.assert_allclose(X_BP.translation(), [0, 0, 0.079], atol=1e-12)
