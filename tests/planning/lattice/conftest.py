"""A small lattice (2 cm, 5 x 5 points) in a scene with a wall along the hand's right,
and the small ch. 7 problem on it."""

from dataclasses import replace

import numpy as np
import pytest

from models.herb.scene import Obstacle, PlanarPose, SceneSpec
from models.objects import ObjectSpec
from planning.lattice.grid import LatticeSpec
from planning.lattice.ik_table import load_ik_table

#: Half the planar hand's width (m): its outline spans y in [-6, 6] cm.
HAND_HALF_WIDTH_M = 0.06

SMALL_PROBLEM = """trust_x_m: [0.0, 0.20]
trust_y_m: [-0.06, 0.06]
free_cell_m: 0.02
contact_states: false
step_m: 0.02
actions:
  forward: [1, 0]
  back: [-1, 0]
  left: [0, 1]
  right: [0, -1]
samples_per_state: 6
"""


def wall_scene() -> SceneSpec:
    """The empty scene, the bottle, and a wall along the hand's right side, 1 cm from the
    planar hand's outline (6 cm from the palm's axis) and ending 10 cm ahead of the palm:
    free at the start, hit by a 2 cm move right, and clear of a bottle ahead of the
    fingertips."""
    scene = SceneSpec.load("empty", object_override="bottle")
    start = scene.hand_start
    wall = ObjectSpec(name="wall", shape="box", height_m=0.2, mass_kg=1.0,
                      material=scene.object.material, rgba=(0.5, 0.5, 0.5, 1.0),
                      size_m=(0.20, 0.04))
    pose = PlanarPose(start.x, start.y - HAND_HALF_WIDTH_M - 0.01 - 0.02, 0.0)
    return replace(scene, obstacles=(Obstacle(wall, pose),))


@pytest.fixture(scope="session")
def wall():
    return wall_scene()


@pytest.fixture(scope="session")
def small_spec(wall) -> LatticeSpec:
    return LatticeSpec(start=tuple(wall.hand_start.as_array()), resolution_m=0.02,
                       x_range_m=(-0.04, 0.04), y_range_m=(-0.04, 0.04))


@pytest.fixture(scope="session")
def small_table(wall, small_spec, tmp_path_factory):
    return load_ik_table(wall, small_spec, cache_dir=tmp_path_factory.mktemp("cache"),
                         progress=False)


@pytest.fixture(scope="session")
def moves() -> np.ndarray:
    """forward, back, left, right by 2 cm (hand frame)."""
    return np.array([[0.02, 0, 0], [-0.02, 0, 0], [0, 0.02, 0], [0, -0.02, 0]])
