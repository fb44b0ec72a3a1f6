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


@pytest.fixture(scope="session")
def small_hand_model():
    """A small hand-relative planning POMDP: the ch. 6 box, fingertip sensors, a 22 cm x
    16 cm trust region and 4 Monte Carlo samples per state (a few seconds to build)."""
    import numpy as np

    from models.planar.world import PlanarWorld
    from planning.hand_discretization import HandProblemSpec
    from planning.hand_pomdp import build_hand_pomdp

    world = PlanarWorld.load("small_box", "fingertips")
    spec = HandProblemSpec(trust_x_m=(0.0, 0.22), trust_y_m=(-0.08, 0.08),
                           samples_per_state=4)
    return build_hand_pomdp(world, spec, rng=np.random.default_rng(0), progress=False)
