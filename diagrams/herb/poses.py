"""Where the palm and the object are, in the plane, from the plant's body poses."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, LeafSystem

from models.herb.mount import planar_palm_pose
from models.herb.world import HerbWorld
from models.pose import transform_to_planar


class PlanarPoses(LeafSystem):
    """The palm's and the object's planar world poses from the plant's body poses.

    Input port: ``body_poses`` (the plant's, abstract).
    Output ports: ``palm_pose`` (3), ``object_pose`` (3): x m, y m, theta rad (world);
    ``object_tilt`` (1): the angle (rad) between the object's vertical axis and the
    world's (a toppled object's planar pose means nothing).
    """

    def __init__(self, plant: MultibodyPlant, world: HerbWorld):
        super().__init__()
        palm = world.hand.palm_frame
        self._palm_body = int(palm.body().index())
        self._X_BP = palm.GetFixedPoseInBodyFrame()
        self._object_body = int(world.object_body.index())
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        self.DeclareVectorOutputPort("palm_pose", 3, self._palm)
        self.DeclareVectorOutputPort("object_pose", 3, self._object)
        self.DeclareVectorOutputPort("object_tilt", 1, self._tilt)

    def _palm(self, context, output: BasicVector) -> None:
        X_WB = self._poses.Eval(context)[self._palm_body]
        output.SetFromVector(planar_palm_pose(X_WB @ self._X_BP))

    def _object(self, context, output: BasicVector) -> None:
        output.SetFromVector(transform_to_planar(self._poses.Eval(context)[self._object_body]))

    def _tilt(self, context, output: BasicVector) -> None:
        z = self._poses.Eval(context)[self._object_body].rotation().col(2)
        output.SetFromVector([np.arccos(np.clip(z[2], -1.0, 1.0))])
