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


@pytest.fixture(scope="session")
def box_world():
    """The planar world with the thesis' box and the medium sensor layout."""
    from models.planar.world import PlanarWorld

    return PlanarWorld.load("box", "medium")


@pytest.fixture(scope="session")
def box_manifold(box_world):
    """The analytic contact manifold of the box (3 deg, 1 mm: a little coarser than the
    thesis' 1.15 deg to keep the suite quick)."""
    import numpy as np

    from estimation.manifolds import AnalyticManifold

    return AnalyticManifold(box_world, dtheta_rad=np.deg2rad(3.0))
