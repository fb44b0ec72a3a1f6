"""The planar hand agrees with the 3-D Drake hand: at object poses near the hand, the planar
signed distance equals Drake's signed distance between the hand's collision geometry and
a tall prism of the object's outline (the slice at push height), within 1 mm."""

import numpy as np
import pytest
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.framework import DiagramBuilder

from models.bodies import add_geometry
from models.contact import OBJECT_MATERIAL
from models.herb.hand import BarrettHandSpec, add_barrett_hand
from models.herb.tactile import TactileLayout
from models.objects import ObjectSpec
from models.planar.polygon import ConvexPolygons, signed_distances
from models.planar.world import PlanarWorld

# Planar hand frame H -> palm frame P: H's x is the palm's z, H's y the palm's y, H's z
# (up) the palm's -x. An object's body z is H's z.
R_P_H = RotationMatrix(np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]))


def _drake_distances(poses: np.ndarray) -> np.ndarray:
    spec = BarrettHandSpec.load()
    box = ObjectSpec.load("box")
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=1e-3, discrete_contact_approximation="lagged"), builder)
    hand = add_barrett_hand(plant, spec, TactileLayout())
    plant.WeldFrames(plant.world_frame(), hand.base.body_frame(), RigidTransform())
    body = plant.AddRigidBody("prism", plant.AddModelInstance("prism"),
                              SpatialInertia(1.0, np.zeros(3), UnitInertia(1, 1, 1)))
    object_geometry = add_geometry(plant, body, RigidTransform(),
                                   Box(box.size_m[0], box.size_m[1], 0.3), "prism",
                                   OBJECT_MATERIAL, (1, 0, 0, 1))
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyContextFromRoot(context)
    assert np.allclose(hand.preshape, 0.0)  # the default joint angles are the push preshape
    X_WP = spec.X_BaseP
    out = np.empty(len(poses))
    for i, (x, y, theta) in enumerate(poses):
        R = R_P_H.multiply(RotationMatrix.MakeZRotation(theta))
        X_PO = RigidTransform(R, R_P_H.multiply(np.array([x, y, 0.0])))
        plant.SetFreeBodyPose(plant_context, body, X_WP @ X_PO)
        query = plant.get_geometry_query_input_port().Eval(plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(0.1)
        out[i] = min(p.distance for p in pairs
                     if object_geometry in (p.id_A, p.id_B))
    return out


@pytest.fixture(scope="module")
def near_poses(box_world):
    rng = np.random.default_rng(4)
    candidates = np.column_stack([rng.uniform(0.05, 0.22, 3000),
                                  rng.uniform(-0.14, 0.14, 3000),
                                  rng.uniform(-np.pi, np.pi, 3000)])
    d = signed_distances(box_world.hand.parts, box_world.shape, candidates,
                         exact_within=0.05).min(axis=1)
    near = candidates[(d > -0.004) & (d < 0.02)]
    return near[:40]


def test_planar_signed_distance_matches_drake_within_1mm(box_world: PlanarWorld, near_poses):
    planar = signed_distances(box_world.hand.parts,
                              ConvexPolygons.from_list([ObjectSpec.load("box").footprint()]),
                              near_poses, exact_within=0.05).min(axis=1)
    drake = _drake_distances(near_poses)
    assert len(near_poses) == 40
    assert np.sum(planar < 0) >= 3  # some overlapping poses are in the sample
    assert np.max(np.abs(planar - drake)) < 1e-3, np.c_[near_poses, planar, drake]
