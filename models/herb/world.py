"""Populate a ``MultibodyPlant`` with a whole scene: HERB's arm and hand, table, object,
obstacles, and the collision filters that go with them.

This is shared by the simulation diagram (``diagrams/``), which adds the movable object,
and by the kinematic model used for inverse kinematics (``models/herb/kinematics.py``), which
leaves it out: the hand is meant to touch the object, never the table or the obstacles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, CollisionFilterDeclaration, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, RigidBody

from models.bodies import add_geometry
from models.contact import TABLE_MATERIAL
from models.herb.hand import BarrettHandSpec, HandModel, add_barrett_hand
from models.herb.mount import HerbMount, X_W_palm, add_wam
from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout
from models.objects import add_object
from models.pose import planar_to_transform

TABLE_RGBA = (0.62, 0.48, 0.33, 1.0)


@dataclass
class HerbWorld:
    """Handles to what :func:`populate_world` added.

    Attributes:
        wam: the arm's model instance (7 actuated joints).
        hand: the hand (instance, palm frame, patch geometries, actuators, preshape).
        object_body: the free movable object, or ``None`` in a kinematic model.
        table_top_z_m: world height of the table top (m).
        palm_height_m: world height of the palm frame when pushing (m).
    """

    scene: SceneSpec
    mount: HerbMount
    hand_spec: BarrettHandSpec
    layout: TactileLayout
    wam: ModelInstanceIndex
    hand: HandModel
    object_body: RigidBody | None
    table_top_z_m: float
    palm_height_m: float

    def hand_joint_positions(self) -> dict[str, float]:
        """Hand joint angles (rad) of the preshape, by joint name, with the coupled joints
        (F2 spread, distal joints) at their constrained values."""
        spread, proximal = self.hand.preshape[0], self.hand.preshape[1]
        positions = {"bh_f1_spread": spread, "bh_f2_spread": spread}
        for finger in ("f1", "f2", "f3"):
            positions[f"bh_{finger}_proximal"] = proximal
            positions[f"bh_{finger}_distal"] = proximal * self.hand_spec.distal_coupling
        return positions

    def robot_positions(self, plant: MultibodyPlant, q_arm: np.ndarray,
                        q: np.ndarray | None = None) -> np.ndarray:
        """The plant's position vector with the arm at ``q_arm`` (7,) rad and the hand in
        its preshape; other entries copied from ``q`` (default: the plant's defaults)."""
        q = plant.GetDefaultPositions() if q is None else np.array(q, dtype=float)
        for k in range(7):
            joint = plant.GetJointByName(f"wam_j{k + 1}", self.wam)
            q[joint.position_start()] = q_arm[k]
        for name, value in self.hand_joint_positions().items():
            q[plant.GetJointByName(name, self.hand.instance).position_start()] = value
        return q

    def X_W_palm(self, pose) -> RigidTransform:
        """World pose of the palm for a planar hand pose (x m, y m, theta rad)."""
        return X_W_palm(pose, self.palm_height_m)

    def X_W_object_initial(self) -> RigidTransform:
        """The movable object's initial world pose, resting on the table."""
        p = self.scene.object_pose
        return planar_to_transform(p.x, p.y, p.theta,
                                   self.table_top_z_m + self.scene.object.height_m / 2)


def populate_world(
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    scene: SceneSpec,
    *,
    layout: TactileLayout,
    hand_spec: BarrettHandSpec | None = None,
    mount: HerbMount | None = None,
    include_object: bool = True,
) -> HerbWorld:
    """Add everything in ``scene`` to an un-finalised plant and declare collision filters
    (see :func:`_filter_collisions`)."""
    hand_spec = hand_spec or BarrettHandSpec.load()
    mount = mount or HerbMount.load()
    wam = add_wam(plant, mount, scene.arm)
    hand = add_barrett_hand(plant, hand_spec, layout)
    plant.WeldFrames(plant.GetFrameByName("wam7", wam), hand.base.body_frame(),
                     RigidTransform([0.0, 0.0, hand_spec.ft_thickness]))
    plant.set_gravity_enabled(wam, False)
    plant.set_gravity_enabled(hand.instance, False)

    table_top = scene.table.top_height_m
    env = plant.AddModelInstance("environment")
    _add_table(plant, scene, env)
    _add_herb_body(plant, mount, env)
    for obstacle in scene.obstacles:
        body = add_object(plant, obstacle.spec, env, name=obstacle.spec.name)
        p = obstacle.pose
        plant.WeldFrames(plant.world_frame(), body.body_frame(),
                         planar_to_transform(p.x, p.y, p.theta,
                                             table_top + obstacle.spec.height_m / 2))
    object_body = None
    if include_object:
        movable = plant.AddModelInstance("object")
        object_body = add_object(plant, scene.object, movable, name="object")

    _filter_collisions(plant, scene_graph, wam, hand)
    world = HerbWorld(scene, mount, hand_spec, layout, wam, hand, object_body, table_top,
                  table_top + scene.hand_height_m)
    if include_object:
        plant.SetDefaultFloatingBaseBodyPose(object_body, world.X_W_object_initial())
    return world


def _filter_collisions(plant: MultibodyPlant, scene_graph: SceneGraph,
                       wam: ModelInstanceIndex, hand: HandModel) -> None:
    """Exclude the contact pairs that the primitive geometry gets wrong.

    - The hand's own geometries overlap by construction (pads on links, knuckles in the
      palm) and never collide with each other.
    - The wrist (wam5-wam7) and the hand are one compact assembly; their primitives touch
      at every configuration.
    - The shoulder (wam_base-wam3): the J1 housing and the upper arm's cylinder overlap
      when J2 is near its limits, which the real arm's shape allows.
    Drake already filters bodies joined by a joint.
    """
    def geometry(names, instance):
        return plant.CollectRegisteredGeometries(
            [plant.GetBodyByName(name, instance) for name in names])

    hand_geometry = plant.CollectRegisteredGeometries(
        [plant.get_body(i) for i in plant.GetBodyIndices(hand.instance)])
    wrist = geometry(("wam5", "wam6", "wam7"), wam)
    shoulder = geometry(("wam_base", "wam1", "wam2", "wam3"), wam)
    manager = scene_graph.collision_filter_manager()
    manager.Apply(CollisionFilterDeclaration().ExcludeWithin(hand_geometry))
    manager.Apply(CollisionFilterDeclaration().ExcludeWithin(wrist))
    manager.Apply(CollisionFilterDeclaration().ExcludeBetween(hand_geometry, wrist))
    manager.Apply(CollisionFilterDeclaration().ExcludeWithin(shoulder))


def _add_herb_body(plant: MultibodyPlant, mount: HerbMount, instance) -> None:
    """HERB's torso: a column from the floor to just below the arm mounts, behind the
    shoulders (a collision obstacle for the arm as well as a visual)."""
    body = plant.AddRigidBody("herb_torso", instance)
    top = mount.shoulder_height_m - 0.2
    size = (0.35, 2 * mount.shoulder_lateral_offset_m + 0.1, top)
    X = RigidTransform([mount.shoulder_forward_offset_m - 0.55, 0.0, top / 2])
    add_geometry(plant, body, X, Box(*size), "herb_torso", TABLE_MATERIAL, (0.2, 0.2, 0.22, 1.0))
    plant.WeldFrames(plant.world_frame(), body.body_frame())


def _add_table(plant: MultibodyPlant, scene: SceneSpec, instance: ModelInstanceIndex) -> None:
    table = scene.table
    body = plant.AddRigidBody("table", instance)
    depth, width = table.size_m
    add_geometry(plant, body, RigidTransform(), Box(depth, width, table.thickness_m), "table_top",
                 TABLE_MATERIAL, TABLE_RGBA)
    cx, cy = table.center_xy_m
    plant.WeldFrames(plant.world_frame(), body.body_frame(),
                     RigidTransform([cx, cy, table.top_height_m - table.thickness_m / 2]))
