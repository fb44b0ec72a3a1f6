"""Each arm of :mod:`models.arms.spec` as a Drake ``MultibodyPlant`` with collision geometry,
so one code path (forward kinematics, signed distance, the Drake reference queries) serves
the planar arms and HERB's WAM alike.

A planar arm is built here from its link lengths: one body per link, a revolute joint
about z at the base and at the end of each link, the sensor and body balls registered as
sphere geometry on their links (so Meshcat and Drake's queries see what the estimator
models), the obstacles welded to the world. The WAM is HERB's kinematic model of a scene
(:func:`models.herb.kinematics.robot_diagram`), with the hand in its preshape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Cylinder, GeometryId, Sphere
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    RevoluteJoint,
    SpatialInertia,
    UnitInertia,
)
from pydrake.planning import RobotDiagram, RobotDiagramBuilder

from models.arms.spec import ArmSpec, Ball, check_links
from models.bodies import add_geometry
from models.contact import TABLE_MATERIAL
from models.herb.kinematics import robot_diagram
from models.herb.scene import SceneSpec

LINK_RGBA = (0.75, 0.75, 0.80, 1.0)
SENSOR_RGBA = (0.20, 0.55, 0.90, 1.0)
OBSTACLE_RGBA = (0.45, 0.45, 0.45, 1.0)


@dataclass
class ArmModel:
    """A built arm: its Drake diagram and what the estimator needs to know about it.

    Attributes:
        diagram: plant and scene graph (``diagram.plant()``, ``diagram.scene_graph()``).
        joints: the estimated joints, base to tip.
        q_default: (nq,) the plant's full position vector with the estimated joints at 0
            (the hand, for HERB, in its preshape).
        q_indices: (dof,) where the estimated joints sit in the position vector.
        environment_ids: the obstacle (and table) geometries.
        lower, upper: (dof,) joint limits (rad; +-inf for the planar arms).
        continuous: joints without limits, whose angles live on the circle.
        link_names: the robot's bodies, on which balls may sit.
    """

    diagram: RobotDiagram
    joints: list[RevoluteJoint]
    q_default: np.ndarray
    q_indices: np.ndarray
    environment_ids: list[GeometryId]
    lower: np.ndarray
    upper: np.ndarray
    continuous: bool
    link_names: set[str]

    def full_positions(self, q: np.ndarray) -> np.ndarray:
        """The plant's position vector for estimated joints ``q`` (dof,) rad."""
        full = self.q_default.copy()
        full[self.q_indices] = q
        return full


def build_arm(spec: ArmSpec) -> ArmModel:
    """The Drake model of ``spec``.

    Raises:
        ConfigError: a ball on a link the robot does not have, or a bad scene file.
    """
    model = _build_planar(spec) if spec.kind == "planar" else _build_herb(spec)
    check_links(spec, model.link_names)
    return model


def _build_planar(spec: ArmSpec) -> ArmModel:
    builder = RobotDiagramBuilder(time_step=0.0)
    plant = builder.plant()
    instance = plant.AddModelInstance(spec.name)
    inertia = SpatialInertia.MakeFromCentralInertia(0.1, np.zeros(3),
                                                    UnitInertia.SolidSphere(0.01) * 0.1)
    joints, parent_frame = [], plant.world_frame()
    for k, length in enumerate(spec.links_m):
        body = plant.AddRigidBody(f"link_{k}", instance, inertia)
        joints.append(plant.AddJoint(RevoluteJoint(f"joint_{k}", parent_frame,
                                                   body.body_frame(), [0.0, 0.0, 1.0])))
        parent_frame = plant.AddFrame(FixedOffsetFrame(f"link_{k}_end", body.body_frame(),
                                                       RigidTransform([length, 0.0, 0.0])))
    balls = [(b, False) for b in spec.body] + [(b, True) for s in spec.sensors
                                               for b in s.balls]
    for i, (ball, sensing) in enumerate(balls):
        add_geometry(plant, plant.GetBodyByName(ball.link, instance),
                     RigidTransform(list(ball.center_m)), Sphere(ball.radius_m),
                     f"ball_{i}", TABLE_MATERIAL, SENSOR_RGBA if sensing else LINK_RGBA)
    env_ids = []
    for obstacle in spec.obstacles:
        shape = (Sphere(obstacle.radius_m) if obstacle.shape == "sphere"
                 else Box(*obstacle.size_m))
        X = RigidTransform(RollPitchYaw(0.0, 0.0, obstacle.yaw_rad), list(obstacle.center_m))
        env_ids.append(plant.RegisterCollisionGeometry(
            plant.world_body(), X, shape, obstacle.name, TABLE_MATERIAL.proximity_properties()))
        plant.RegisterVisualGeometry(plant.world_body(), X, shape, obstacle.name + "_visual",
                                     np.array(OBSTACLE_RGBA))
    plant.Finalize()
    diagram = builder.Build()
    dof = len(joints)
    return ArmModel(diagram, joints, np.zeros(plant.num_positions()),
                    np.array([j.position_start() for j in joints]), env_ids,
                    np.full(dof, -np.inf), np.full(dof, np.inf), continuous=True,
                    link_names={f"link_{k}" for k in range(dof)})


def _build_herb(spec: ArmSpec) -> ArmModel:
    scene = SceneSpec.load(spec.scene)
    diagram, world = robot_diagram(scene)
    plant = diagram.plant()
    joints = [plant.GetJointByName(f"wam_j{k + 1}", world.wam) for k in range(7)]
    robot = {world.wam, world.hand.instance}
    inspector = diagram.scene_graph().model_inspector()
    env_ids = [gid for gid in inspector.GetAllGeometryIds()
               if inspector.GetProximityProperties(gid) is not None
               and plant.GetBodyFromFrameId(inspector.GetFrameId(gid)).model_instance()
               not in robot]
    q_default = world.robot_positions(plant, np.zeros(7))
    indices = np.array([j.position_start() for j in joints])
    return ArmModel(diagram, joints, q_default, indices, env_ids,
                    plant.GetPositionLowerLimits()[indices],
                    plant.GetPositionUpperLimits()[indices], continuous=False,
                    link_names={plant.get_body(i).name() for instance in robot
                                for i in plant.GetBodyIndices(instance)})


def geometry_balls(model: ArmModel, links: tuple[str, ...]) -> tuple[Ball, ...]:
    """Balls covering the collision geometry of ``links``, in each link's frame.

    A sphere is itself; a cylinder, balls of its radius along its axis; a box, balls that
    circumscribe its cross-section (radius half the diagonal of its two smaller
    dimensions) along its longest dimension. Balls are spaced at most one radius apart,
    the end ones half a radius inside the ends: the cover is a little larger than the
    geometry across and a little shorter at the corners, so it errs towards contact.

    Raises:
        ValueError: a geometry of another shape.
    """
    plant = model.diagram.plant()
    inspector = model.diagram.scene_graph().model_inspector()
    balls = []
    for link in links:
        body = plant.GetBodyByName(link)
        for gid in plant.GetCollisionGeometriesForBody(body):
            shape, X = inspector.GetShape(gid), inspector.GetPoseInFrame(gid)
            if isinstance(shape, Sphere):
                local, radius = [np.zeros(3)], shape.radius()
            elif isinstance(shape, Cylinder):
                radius = shape.radius()
                local = [np.array([0.0, 0.0, z]) for z in _along(shape.length(), radius)]
            elif isinstance(shape, Box):
                size = np.array(shape.size())
                order = np.argsort(size)
                radius = float(np.hypot(size[order[0]], size[order[1]]) / 2)
                local = []
                for z in _along(size[order[2]], radius):
                    point = np.zeros(3)
                    point[order[2]] = z
                    local.append(point)
            else:
                raise ValueError(f"{link}: geometry {inspector.GetName(gid)!r} is a "
                                 f"{type(shape).__name__}; spheres, cylinders and boxes "
                                 "can be covered by balls")
            balls += [Ball(link, tuple(float(v) for v in X.multiply(p)), float(radius))
                      for p in local]
    return tuple(balls)


def _along(length: float, radius: float) -> np.ndarray:
    """Centres at most ``radius`` apart along a segment of ``length``, the end ones half a
    radius inside its ends."""
    half = max(length / 2 - radius / 2, 0.0)
    count = int(np.ceil(2 * half / radius)) + 1 if half > 0 else 1
    return np.linspace(-half, half, count)
