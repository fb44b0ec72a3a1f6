"""Scenes: where the robot, table, movable object, obstacles and the hand's start are.

A scene is a YAML file (built-in: ``empty``, ``right_obstacles``, ``left_obstacles``,
``cul_de_sac``; or any path). Poses on the table are planar, world frame:
``{x_m, y_m, theta_deg}``. The world frame has its origin on the floor under HERB's base
centre, x forward, z up. Object and obstacle files are named as built-in objects or as
paths relative to the scene file.

Every physical quantity is required (the table's size, height, centre and thickness, every
pose's ``x_m``, ``y_m`` and ``theta_deg``, the hand's height), with two deliberate
exceptions for obstacles, on which every built-in scene relies:

- an obstacle's ``mass_kg`` may be omitted (:data:`OBSTACLE_MASS_KG`): obstacles are
  welded to the world, so their mass never enters the dynamics;
- an obstacle without a ``contact`` section is made of
  :data:`~models.contact.OBSTACLE_MATERIAL` (5e6 Pa, mu 0.5).

``obstacles`` may be omitted for a table without any; ``name`` defaults to the file's
stem, ``description`` to nothing and ``arm`` to ``right``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.config import ConfigError, Fields, relative_to_file, resolve_asset
from models.contact import OBSTACLE_MATERIAL
from models.objects import ObjectSpec

ARMS = ("right", "left")
#: Mass (kg) of an obstacle whose entry gives none: obstacles are welded to the world, so
#: it never enters the dynamics (Drake still wants a positive mass for every body).
OBSTACLE_MASS_KG = 1.0


@dataclass(frozen=True)
class PlanarPose:
    """A pose in the table plane, world frame: x, y (m) and theta (rad)."""

    x: float
    y: float
    theta: float

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta])

    @staticmethod
    def from_fields(fields: Fields) -> PlanarPose:
        pose = PlanarPose(
            x=fields.number("x_m", min=-5.0, max=5.0),
            y=fields.number("y_m", min=-5.0, max=5.0),
            theta=np.deg2rad(fields.number("theta_deg", min=-360.0, max=360.0)),
        )
        fields.done()
        return pose


@dataclass(frozen=True)
class TableSpec:
    """The table: top height above the floor, size (depth along x, width along y) and the
    centre of its top in the plane, all in m."""

    top_height_m: float = 0.735
    size_m: tuple[float, float] = (0.74, 1.85)
    center_xy_m: tuple[float, float] = (0.80, 0.0)
    thickness_m: float = 0.04

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Is the planar point (x, y) on the table top, at least ``margin`` m from its edges?"""
        return (abs(x - self.center_xy_m[0]) <= self.size_m[0] / 2 - margin
                and abs(y - self.center_xy_m[1]) <= self.size_m[1] / 2 - margin)


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle standing on the table."""

    spec: ObjectSpec
    pose: PlanarPose


@dataclass(frozen=True)
class SceneSpec:
    """A whole scene.

    Attributes:
        name: scene name.
        description: one line for humans.
        arm: which of HERB's arms acts (``right`` or ``left``).
        table: the table.
        object: the movable object.
        object_pose: its initial planar pose (world).
        hand_height_m: palm-frame height above the table top (m) for planar pushing.
        hand_start: the hand's initial planar pose (world); theta is the push direction.
        obstacles: static obstacles on the table.
    """

    name: str
    description: str
    arm: str
    table: TableSpec
    object: ObjectSpec
    object_pose: PlanarPose
    hand_height_m: float
    hand_start: PlanarPose
    obstacles: tuple[Obstacle, ...] = ()

    @staticmethod
    def load(name_or_path: str | Path, *, object_override: str | Path | None = None) -> SceneSpec:
        """Load a scene by built-in name or path; ``object_override`` replaces its object.

        Raises:
            ConfigError: naming the file and field of any malformed entry.
        """
        path = resolve_asset("scenes", name_or_path)
        fields = Fields.from_file(path)
        table_f = fields.sub("table")
        table = TableSpec(
            top_height_m=table_f.number("top_height_m", min=0.1, max=2.0),
            size_m=table_f.vector("size_m", 2, min=0.1, max=5.0),
            center_xy_m=table_f.vector("center_xy_m", 2, min=-5.0, max=5.0),
            thickness_m=table_f.number("thickness_m", min=0.005, max=0.5),
        )
        table_f.done()
        object_f = fields.sub("object")
        scene_object = relative_to_file(path, object_f.string("name"))
        object_name = object_override or scene_object
        try:
            scene_object_spec = ObjectSpec.load(object_name)
        except ConfigError as err:
            if object_override is not None or str(path) in str(err):
                raise
            raise object_f.error("name", str(err)) from None  # say which scene named it
        object_pose = PlanarPose.from_fields(object_f.sub("pose"))
        object_f.done()
        hand_f = fields.sub("hand")
        hand_height = hand_f.number("height_above_table_m", min=0.0, max=0.5)
        hand_start = PlanarPose.from_fields(hand_f.sub("start"))
        hand_f.done()
        obstacles = []
        for item in fields.items("obstacles", []):
            pose = PlanarPose.from_fields(item.sub("pose"))
            spec = ObjectSpec.from_fields(item, default_name=f"obstacle_{len(obstacles)}",
                                          default_material=OBSTACLE_MATERIAL,
                                          default_mass_kg=OBSTACLE_MASS_KG)
            item.done()
            obstacles.append(Obstacle(spec, pose))
        names = [o.spec.name for o in obstacles]
        if len(set(names)) != len(names):
            raise fields.error("obstacles", f"obstacle names must be distinct, got {names}")
        scene = SceneSpec(
            name=fields.string("name", path.stem),
            description=fields.string("description", ""),
            arm=fields.string("arm", "right", choices=ARMS),
            table=table,
            object=scene_object_spec,
            object_pose=object_pose,
            hand_height_m=hand_height,
            hand_start=hand_start,
            obstacles=tuple(obstacles),
        )
        fields.done()
        for label, pose in [("object.pose", object_pose), ("hand.start", hand_start)] + [
            (f"obstacles[{i}].pose", o.pose) for i, o in enumerate(obstacles)
        ]:
            if not table.contains(pose.x, pose.y):
                raise fields.error(label, f"({pose.x}, {pose.y}) m is not on the table")
        return scene
