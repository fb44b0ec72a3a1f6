"""The WAM model against the published DH table and limits (shared/reference/herb_facts.md)."""

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from models.herb.mount import WAM_SDF

# Independent restatement of the reference: (a m, alpha rad, d m), standard DH, theta offsets 0.
DH = [(0, -np.pi / 2, 0), (0, np.pi / 2, 0), (0.045, -np.pi / 2, 0.55), (-0.045, np.pi / 2, 0),
      (0, -np.pi / 2, 0.30), (0, np.pi / 2, 0), (0, 0, 0.06)]
LOWER = [-2.6, -2.0, -2.8, -0.9, -4.76, -1.6, -3.0]
UPPER = [2.6, 2.0, 2.8, 3.1, 1.24, 1.6, 3.0]
VELOCITY = [0.75, 0.75, 2.0, 2.0, 2.5, 2.5, 2.5]
MASSES = {"wam_base": 9.971, "wam1": 10.768, "wam2": 3.875, "wam3": 1.802, "wam4": 2.400,
          "wam5": 0.124, "wam6": 0.418, "wam7": 0.0686}


def dh_transform(a, alpha, d, theta):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                     [0, sa, ca, d], [0, 0, 0, 1]])


@pytest.fixture(scope="module")
def wam():
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(WAM_SDF)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("wam_base"))
    plant.Finalize()
    return plant, plant.CreateDefaultContext()


def test_forward_kinematics_equals_dh_product(wam):
    plant, context = wam
    rng = np.random.default_rng(7)
    base_to_shoulder = np.eye(4)
    base_to_shoulder[:3, 3] = [0.22, 0.14, 0.346]
    for _ in range(50):
        q = rng.uniform(LOWER, UPPER)
        plant.SetPositions(context, q)
        expected = base_to_shoulder.copy()
        for k, (a, alpha, d) in enumerate(DH):
            expected = expected @ dh_transform(a, alpha, d, q[k])
            frame = plant.GetFrameByName(f"wam{k + 1}")
            actual = frame.CalcPoseInWorld(context).GetAsMatrix4()
            np.testing.assert_allclose(actual[:3, 3], expected[:3, 3], atol=1e-9)
            np.testing.assert_allclose(actual[:3, :3], expected[:3, :3], atol=1e-9)


def test_flange_is_091_m_above_shoulder_at_zero(wam):
    plant, context = wam
    plant.SetPositions(context, np.zeros(7))
    p = plant.GetFrameByName("wam7").CalcPoseInWorld(context).translation()
    np.testing.assert_allclose(p, [0.22, 0.14, 0.346 + 0.91], atol=1e-12)


def test_joint_limits_and_velocity_limits_equal_reference(wam):
    plant, _ = wam
    np.testing.assert_array_equal(plant.GetPositionLowerLimits(), LOWER)
    np.testing.assert_array_equal(plant.GetPositionUpperLimits(), UPPER)
    np.testing.assert_array_equal(plant.GetVelocityUpperLimits(), VELOCITY)


def test_link_masses_equal_reference(wam):
    plant, _ = wam
    for name, mass in MASSES.items():
        assert plant.GetBodyByName(name).default_mass() == pytest.approx(mass)
