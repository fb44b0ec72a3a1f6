"""Seed 003's pusher-slider rig as a Drake world: two rods on a planar carriage push a
steel object across a table; hydroelastic contact (Yu and Rodriguez, ICRA 2018, sec. V-A).

The rig's numbers live in ``models/assets/pusher_slider.yaml`` (or a user's file of the
same fields): :class:`PusherSliderRig` reads and checks them. :func:`add_pusher_slider`
builds the plant:

- The **carriage** has three joints (prismatic x, prismatic y, revolute z), each with an
  actuator that tracks a desired state by Drake's implicit PD control, so the robot's
  stiff position control is modelled without a controller diagram. Its two rods are
  rigid-hydroelastic cylinders on the carriage body; their tips clear the table by
  ``pusher_clearance_m``.
- The **object** is a free, rigid-hydroelastic body; the **rods** are stiff compliant
  cylinders.
- The **table** is compliant hydroelastic (see :data:`TABLE_MODULUS_PA` for why).

Friction: Drake combines two geometries' coefficients as ``2 mu_a mu_b / (mu_a + mu_b)``.
The object keeps its file's coefficient ``mu_o``; the rods get the one that makes the rod-
object pair ``pusher_object_mu`` and the table the one that makes the object-surface pair
the chosen surface's coefficient, ``mu_t = mu mu_o / (2 mu_o - mu)``. That needs
``mu < 2 mu_o``; the loader says so when a file breaks it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Cylinder, GeometryId
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    ModelInstanceIndex,
    PdControllerGains,
    PrismaticJoint,
    RevoluteJoint,
    SpatialInertia,
    UnitInertia,
)

from models.bodies import add_geometry, tessellated_prism_mesh
from models.config import ASSETS_DIR, Fields
from models.contact import ContactMaterial
from models.objects import ObjectSpec
from models.pose import planar_to_transform

DEFAULT_RIG = ASSETS_DIR / "pusher_slider.yaml"
TABLE_RGBA = (0.55, 0.42, 0.3, 1.0)
ROD_RGBA = (0.3, 0.3, 0.35, 1.0)
CARRIAGE_RGBA = (0.9, 0.55, 0.1, 1.0)
#: The table is compliant and the object rigid, so that the support pressure is uniform
#: under the object: a compliant box's pressure field grows with the depth below its
#: nearest face, which under a flat object resting on a thick table is the same
#: everywhere. (A compliant object's field peaks at its centre instead.)
TABLE_MODULUS_PA = 1.0e7
TABLE_THICKNESS_M = 0.1
#: Grid (m) of the object's support-face triangulation (see
#: :func:`models.bodies.tessellated_prism_mesh`). Measured on rect1's one-finger pushes
#: (the limit surface's c fitted to the simulated twist, and the wall time of the 41 s
#: standard procedure): untessellated 0.020 m, 18 s; 30 mm grid 0.027 m, 21 s; 15 mm
#: 0.027 m, 34 s; 5 mm 0.027 m, 155 s. 30 mm is converged.
SUPPORT_GRID_M = 0.03
#: The rods are stiff compliant cylinders (a rigid rod against the rigid object would fall
#: back to point contact).
ROD_MODULUS_PA = 1.0e8
#: Carriage PD gains: position (N/m, N m/rad) and damping; stiff like an industrial arm.
CARRIAGE_KP = (2.0e4, 2.0e4, 200.0)
CARRIAGE_KD = (8.0e2, 8.0e2, 8.0)


@dataclass(frozen=True)
class ForceSensorSpec:
    """Per-rod force sensing. Attributes: ``rate_hz``; ``noise_n`` per-axis standard
    deviation (N); ``contact_threshold_n`` (N), |F| at or above it counts as contact;
    ``position_noise_m`` (m), per-axis error of the rod positions from kinematics."""

    rate_hz: float = 250.0
    noise_n: float = 0.05
    contact_threshold_n: float = 0.3
    position_noise_m: float = 0.0002


@dataclass(frozen=True)
class CameraSpec:
    """A pose-measuring camera (AprilTag). ``position_m`` (3,) in the world (m); ``bias_m``
    (2,) and ``bias_deg``: a fixed calibration error; ``noise_m``/``noise_deg``: per-frame
    standard deviations; ``tag_size_m``: the tag's side (the tag is centred on the object's
    top face and every corner must be in sight)."""

    rate_hz: float = 30.0
    position_m: tuple[float, float, float] = (0.0, -0.35, 0.55)
    bias_m: tuple[float, float] = (0.006, -0.004)
    bias_deg: float = 1.5
    noise_m: float = 0.003
    noise_deg: float = 1.5
    tag_size_m: float = 0.03


@dataclass(frozen=True)
class PusherSliderRig:
    """The rig (see ``models/assets/pusher_slider.yaml`` for every field's meaning and
    source). Lengths in m, speeds in m/s, forces in N."""

    pusher_diameter_m: float = 0.00625
    pusher_length_m: float = 0.115
    pusher_spacing_m: float = 0.04
    pusher_clearance_m: float = 0.002
    pusher_object_mu: float = 0.25
    push_speed_m_per_s: float = 0.06
    transit_speed_m_per_s: float = 0.09
    surface: str = "plywood"
    surfaces: dict[str, float] = field(default_factory=lambda: {
        "abs": 0.16, "delrin": 0.15, "plywood": 0.28, "polyurethane": 0.35})
    force_sensor: ForceSensorSpec = ForceSensorSpec()
    camera: CameraSpec = CameraSpec()
    carriage_size_m: tuple[float, float, float] = (0.08, 0.08, 0.02)
    wrist_size_m: tuple[float, float, float] = (0.06, 0.06, 0.35)
    source: str = ""

    @property
    def pusher_radius_m(self) -> float:
        return self.pusher_diameter_m / 2

    @property
    def surface_mu(self) -> float:
        return self.surfaces[self.surface]

    def pusher_offsets(self) -> np.ndarray:
        """(2, 2) the rods' positions in the carriage frame (m): on the carriage's y axis,
        ``pusher_spacing_m`` apart; the carriage pushes along its +x."""
        half = self.pusher_spacing_m / 2
        return np.array([[0.0, half], [0.0, -half]])

    def with_surface(self, surface: str) -> PusherSliderRig:
        if surface not in self.surfaces:
            raise ValueError(f"unknown surface {surface!r}; the rig {self.source or 'default'} "
                             f"has {', '.join(self.surfaces)}")
        return replace(self, surface=surface)

    @staticmethod
    def load(path: str | Path = DEFAULT_RIG) -> PusherSliderRig:
        """Read a rig file; every field is required and checked (file and field named on
        error). The dataclass defaults above are the built-in file's numbers, for code that
        builds a rig directly; a file never falls back on them."""
        fields = Fields.from_file(Path(path))
        surfaces_raw = fields.sub("surfaces")
        surfaces = {}
        for name in surfaces_raw.keys():
            surfaces[name] = surfaces_raw.number(name, min=0.01, max=2.0)
        surfaces_raw.done()
        sensor = fields.sub("force_sensor")
        force = ForceSensorSpec(
            rate_hz=sensor.number("rate_hz", min=1.0, max=5000.0),
            noise_n=sensor.number("noise_n", min=0.0, max=10.0),
            contact_threshold_n=sensor.number("contact_threshold_n", min=1e-3, max=100.0),
            position_noise_m=sensor.number("position_noise_m", min=0.0, max=0.05))
        sensor.done()
        cam = fields.sub("camera")
        camera = CameraSpec(
            rate_hz=cam.number("rate_hz", min=0.1, max=1000.0),
            position_m=cam.vector("position_m", 3, min=-10, max=10),
            bias_m=cam.vector("bias_m", 2, min=-0.5, max=0.5),
            bias_deg=cam.number("bias_deg", min=-45, max=45),
            noise_m=cam.number("noise_m", min=0.0, max=0.5),
            noise_deg=cam.number("noise_deg", min=0.0, max=45),
            tag_size_m=cam.number("tag_size_m", min=1e-3, max=0.5))
        cam.done()
        rig = PusherSliderRig(
            pusher_diameter_m=fields.number("pusher_diameter_m", min=1e-4, max=0.1),
            pusher_length_m=fields.number("pusher_length_m", min=0.02, max=1.0),
            pusher_spacing_m=fields.number("pusher_spacing_m", min=1e-3, max=0.5),
            pusher_clearance_m=fields.number("pusher_clearance_m", min=0.0, max=0.01),
            pusher_object_mu=fields.number("pusher_object_mu", min=0.0, max=2.0),
            push_speed_m_per_s=fields.number("push_speed_m_per_s", min=1e-3, max=1.0),
            transit_speed_m_per_s=fields.number("transit_speed_m_per_s", min=1e-3, max=2.0),
            surface=fields.string("surface", choices=tuple(surfaces)),
            surfaces=surfaces,
            force_sensor=force,
            camera=camera,
            carriage_size_m=fields.vector("carriage_size_m", 3, min=1e-3, max=1.0),
            wrist_size_m=fields.vector("wrist_size_m", 3, min=1e-3, max=2.0),
            source=str(path))
        fields.done()
        return rig


def mu_completing_pair(pair_mu: float, other_mu: float, source: str = "rig") -> float:
    """The coefficient a geometry needs so that Drake's combination with ``other_mu``
    (``2 a b / (a + b)``) gives ``pair_mu``.

    Raises:
        ValueError: when no coefficient can (``pair_mu >= 2 other_mu``).
    """
    if pair_mu <= 0.0:
        return 0.0
    if pair_mu >= 2.0 * other_mu:
        raise ValueError(f"{source}: a pair friction of {pair_mu} needs the object's own "
                         f"coefficient above {pair_mu / 2} (it is {other_mu})")
    return pair_mu * other_mu / (2.0 * other_mu - pair_mu)


@dataclass(frozen=True)
class PusherSliderWorld:
    """Handles into a built pusher-slider plant.

    Attributes:
        carriage: the carriage's model instance (3 actuated joints: x, y, yaw).
        object_body: the free object.
        rod_geometries: (2,) collision geometry ids of the rods, in :meth:`pusher_offsets`
            order.
        object_spec, rig: what was built.
        support_z_m: height of the table top (m); the object rests on it.
    """

    carriage: ModelInstanceIndex
    object_body: object
    rod_geometries: tuple[GeometryId, GeometryId]
    object_spec: ObjectSpec
    rig: PusherSliderRig
    support_z_m: float = 0.0

    def X_WO_initial(self, pose: np.ndarray) -> RigidTransform:
        """The object's 3-D pose resting on the table at planar ``pose`` (x, y, theta)."""
        return planar_to_transform(*pose, z=self.support_z_m + self.object_spec.height_m / 2)


def add_pusher_slider(plant: MultibodyPlant, rig: PusherSliderRig,
                      object_spec: ObjectSpec) -> PusherSliderWorld:
    """Add table, carriage with rods and the object to an un-finalised plant."""
    mu_o = object_spec.material.mu_dynamic
    rod_mu = mu_completing_pair(rig.pusher_object_mu, mu_o, rig.source or "rig")
    table_mu = mu_completing_pair(rig.surface_mu, mu_o, rig.source or "rig")
    table_material = ContactMaterial(mu_static=table_mu, mu_dynamic=table_mu,
                                     hydroelastic_modulus_pa=TABLE_MODULUS_PA)
    rod_material = ContactMaterial(mu_static=rod_mu, mu_dynamic=rod_mu,
                                   hydroelastic_modulus_pa=ROD_MODULUS_PA,
                                   resolution_hint_m=0.002)
    rigid_object = replace(object_spec, material=replace(object_spec.material,
                                                         hydroelastic_modulus_pa=None))

    env = plant.AddModelInstance("table")
    table = plant.AddRigidBody("table", env)
    add_geometry(plant, table, RigidTransform([0, 0, -TABLE_THICKNESS_M / 2]),
                 Box(1.2, 1.2, TABLE_THICKNESS_M), "table_top", table_material, TABLE_RGBA)
    plant.WeldFrames(plant.world_frame(), table.body_frame())

    carriage = plant.AddModelInstance("carriage")
    light = SpatialInertia(0.5, np.zeros(3), UnitInertia.SolidBox(0.05, 0.05, 0.05))
    slide_x = plant.AddRigidBody("carriage_x", carriage, light)
    slide_y = plant.AddRigidBody("carriage_y", carriage, light)
    body = plant.AddRigidBody("carriage", carriage, light)
    z0 = rig.pusher_clearance_m
    joints = [
        plant.AddJoint(PrismaticJoint("x", plant.world_frame(), slide_x.body_frame(),
                                      [1.0, 0.0, 0.0])),
        plant.AddJoint(PrismaticJoint("y", slide_x.body_frame(), slide_y.body_frame(),
                                      [0.0, 1.0, 0.0])),
        plant.AddJoint(RevoluteJoint("yaw", slide_y.body_frame(), body.body_frame(),
                                     [0.0, 0.0, 1.0])),
    ]
    for joint, kp, kd in zip(joints, CARRIAGE_KP, CARRIAGE_KD, strict=True):
        actuator = plant.AddJointActuator(joint.name(), joint)
        actuator.set_controller_gains(PdControllerGains(p=kp, d=kd))
    rods = []
    length = rig.pusher_length_m
    for i, (x, y) in enumerate(rig.pusher_offsets()):
        rods.append(add_geometry(
            plant, body, RigidTransform([x, y, z0 + length / 2]),
            Cylinder(rig.pusher_radius_m, length), f"rod{i}", rod_material, ROD_RGBA))
    cx, cy, cz = rig.carriage_size_m
    top = z0 + length
    add_geometry(plant, body, RigidTransform([0, 0, top + cz / 2]), Box(cx, cy, cz),
                 "carriage_plate", None, CARRIAGE_RGBA)
    wx, wy, wz = rig.wrist_size_m
    add_geometry(plant, body, RigidTransform([0, 0, top + cz + wz / 2]), Box(wx, wy, wz),
                 "wrist", None, CARRIAGE_RGBA)

    movable = plant.AddModelInstance("object")
    object_body = plant.AddRigidBody("object", movable, object_spec.spatial_inertia())
    collision = tessellated_prism_mesh(object_spec.footprint(), object_spec.height_m,
                                       SUPPORT_GRID_M, "object")
    plant.RegisterCollisionGeometry(object_body, RigidTransform(), collision, "object",
                                    rigid_object.material.proximity_properties())
    plant.RegisterVisualGeometry(object_body, RigidTransform(), object_spec.shape3d(),
                                 "object", np.asarray(object_spec.rgba))
    return PusherSliderWorld(carriage, object_body, (rods[0], rods[1]), object_spec, rig)


def occluders(rig: PusherSliderRig) -> tuple[np.ndarray, np.ndarray]:
    """The carriage's parts that can hide the tag, in the carriage frame.

    Returns:
        (cylinders (2, 4): x, y, radius, top z; boxes (2, 6): centre xyz, size xyz), m.
        The rods run from ``pusher_clearance_m`` to their top.
    """
    z0 = rig.pusher_clearance_m
    top = z0 + rig.pusher_length_m
    cylinders = np.array([[x, y, rig.pusher_radius_m, top] for x, y in rig.pusher_offsets()])
    cx, cy, cz = rig.carriage_size_m
    wx, wy, wz = rig.wrist_size_m
    boxes = np.array([[0, 0, top + cz / 2, cx, cy, cz],
                      [0, 0, top + cz + wz / 2, wx, wy, wz]])
    return cylinders, boxes

