"""Shared fixtures: built-in scenes and the (expensive) kinematic model, built once."""

import pytest

from models.kinematics import PlanarHandIK
from models.scene import SceneSpec


@pytest.fixture(scope="session")
def empty_scene() -> SceneSpec:
    return SceneSpec.load("empty")


@pytest.fixture(scope="session")
def empty_ik(empty_scene) -> PlanarHandIK:
    return PlanarHandIK(empty_scene)
