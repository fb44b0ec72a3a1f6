"""The BarrettHand BH-280: its dimensions (data) and its construction in a ``MultibodyPlant``.

Kinematic structure (all lengths from ``models/assets/barrett_hand.yaml``)::

    bh_base (palm, F/T sensor, F3 knuckle; frame "palm" on the palm surface)
      |- bh_f1_knuckle  (revolute "bh_f1_spread" about +z at x = +spread_offset)
      |    `- bh_f1_proximal (revolute "bh_f1_proximal") `- bh_f1_distal ("bh_f1_distal")
      |- bh_f2_knuckle  (revolute "bh_f2_spread" about -z at x = -spread_offset)
      |    `- ... as F1
      `- bh_f3_proximal (revolute, fixed knuckle at y = +knuckle_offset) `- bh_f3_distal

Every finger link has its own frame with z along the link (away from its joint), y towards
the inner (closing) face and x along the joint axis; each finger joint closes the finger
about -x. Couplings are Drake coupler constraints (require a SAP-family discrete solver):
``bh_f2_spread = bh_f1_spread`` and ``distal = distal_coupling * proximal`` on each finger.
Actuated: ``bh_f1_spread`` and the three proximal joints.

Collision geometry is made of boxes and cylinders. The sensing patches of a
:class:`~models.herb.tactile.TactileLayout` are separate collision geometries (inner halves of
the links, the fingertips, palm-pad strips); the rest of the hand is covered by
non-sensing geometry, so changing the layout never changes the hand's shape.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Cylinder, GeometryId
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    Frame,
    JointActuator,
    ModelInstanceIndex,
    PdControllerGains,
    RevoluteJoint,
    RigidBody,
)

from models.bodies import add_geometry, box_inertia, cylinder_inertia
from models.config import ASSETS_DIR, Fields
from models.contact import HAND_MATERIAL, ContactMaterial
from models.herb.tactile import TactileLayout

SENSOR_RGBA = (0.15, 0.45, 0.85, 1.0)
HAND_RGBA = (0.30, 0.30, 0.33, 1.0)
CLOSE_AXIS = np.array([-1.0, 0.0, 0.0])  # finger joints close about -x of the finger frame


@dataclass(frozen=True)
class BarrettHandSpec:
    """Dimensions (m), angles (rad) and masses (kg) of the hand; see barrett_hand.yaml."""

    ft_thickness: float
    ft_radius: float
    ft_mass: float
    palm_surface_height: float
    finger_base_height: float
    palm_radius: float
    pad_thickness: float
    pad_size: tuple[float, float]
    palm_mass: float
    spread_offset: float
    knuckle_offset: float
    proximal_length: float
    distal_length: float
    distal_tip_extra: float
    link_width: float
    link_thickness: float
    tip_length: float
    distal_offset: float
    distal_coupling: float
    knuckle_mass: float
    proximal_mass: float
    distal_mass: float
    proximal_limits: tuple[float, float]
    distal_limits: tuple[float, float]
    spread_limits: tuple[float, float]
    preshape_spread: float
    preshape_proximal: float

    @staticmethod
    def load(path: str | Path | None = None) -> BarrettHandSpec:
        """Read the hand's data file (default: the built-in ``barrett_hand.yaml``)."""
        fields = Fields.from_file(Path(path) if path else ASSETS_DIR / "barrett_hand.yaml")
        ft, palm, fingers, pre = (fields.sub(k) for k in ("ft_sensor", "palm", "fingers",
                                                            "preshape"))
        length = dict(min=0.0, max=0.5)
        mass = dict(min=1e-4, max=10.0)
        spec = BarrettHandSpec(
            ft_thickness=ft.number("thickness", **length),
            ft_radius=ft.number("radius", **length),
            ft_mass=ft.number("mass", **mass),
            palm_surface_height=palm.number("surface_height", **length),
            finger_base_height=palm.number("finger_base_height", **length),
            palm_radius=palm.number("radius", **length),
            pad_thickness=palm.number("pad_thickness", min=1e-3, max=0.05),
            pad_size=palm.vector("pad_size", 2, min=0.01, max=0.3),
            palm_mass=palm.number("mass", **mass),
            spread_offset=fingers.number("spread_offset", **length),
            knuckle_offset=fingers.number("knuckle_offset", **length),
            proximal_length=fingers.number("proximal_length", min=0.01, max=0.5),
            distal_length=fingers.number("distal_length", min=0.01, max=0.5),
            distal_tip_extra=fingers.number("distal_tip_extra", **length),
            link_width=fingers.number("link_width", min=0.002, max=0.1),
            link_thickness=fingers.number("link_thickness", min=0.002, max=0.1),
            tip_length=fingers.number("tip_length", min=0.001, max=0.05),
            distal_offset=fingers.number("distal_offset", min=-np.pi, max=np.pi),
            distal_coupling=fingers.number("distal_coupling", min=0.0, max=2.0),
            knuckle_mass=fingers.number("knuckle_mass", **mass),
            proximal_mass=fingers.number("proximal_mass", **mass),
            distal_mass=fingers.number("distal_mass", **mass),
            proximal_limits=fingers.vector("proximal_limits", 2, min=-np.pi, max=np.pi),
            distal_limits=fingers.vector("distal_limits", 2, min=-np.pi, max=np.pi),
            spread_limits=fingers.vector("spread_limits", 2, min=-np.pi, max=np.pi + 1e-3),
            preshape_spread=pre.number("spread", min=-np.pi, max=np.pi),
            preshape_proximal=pre.number("proximal", min=-np.pi, max=np.pi),
        )
        for sub in (ft, palm, fingers, pre, fields):
            sub.done()
        if spec.tip_length >= spec.distal_length + spec.distal_tip_extra:
            raise fingers.error("tip_length", "must be shorter than the distal link")
        return spec

    @property
    def distal_reach(self) -> float:
        """Length (m) of the distal collision box past the distal joint."""
        return self.distal_length + self.distal_tip_extra

    def finger_base_pose(self, finger: str) -> RigidTransform:
        """Pose in ``bh_base`` of the finger's proximal-joint frame at spread 0.

        For F1/F2 this is expressed in the knuckle frame (on the spread axis); for F3 in
        ``bh_base`` directly. y points towards the palm centre (closing direction).
        """
        if finger == "f3":
            return RigidTransform(
                RotationMatrix.MakeZRotation(np.pi),
                [0.0, self.knuckle_offset, self.finger_base_height],
            )
        return RigidTransform([0.0, -self.knuckle_offset, 0.0])

    @property
    def X_BaseP(self) -> RigidTransform:
        """Pose of the ``palm`` frame (on the palm surface, z out of the palm) in bh_base."""
        return RigidTransform([0.0, 0.0, self.palm_surface_height])


@dataclass
class HandModel:
    """What :func:`add_barrett_hand` put into the plant."""

    instance: ModelInstanceIndex
    base: RigidBody
    palm_frame: Frame
    patch_geometry: dict[str, GeometryId] = field(default_factory=dict)
    actuators: list[JointActuator] = field(default_factory=list)
    preshape: np.ndarray = field(default_factory=lambda: np.zeros(0))


def add_barrett_hand(
    plant: MultibodyPlant,
    spec: BarrettHandSpec,
    layout: TactileLayout,
    *,
    name: str = "barrett_hand",
    material: ContactMaterial = HAND_MATERIAL,
    pd_gains: tuple[float, float] = (20.0, 1.0),
) -> HandModel:
    """Add the hand as a new model instance (not yet attached to anything).

    Args:
        plant: an un-finalised plant registered with a SceneGraph.
        spec: hand dimensions.
        layout: which sensing patches to create.
        name: model-instance name.
        material: contact material of all hand geometry.
        pd_gains: (kp N m/rad, kd N m s/rad) of the finger actuators' implicit PD control.

    Returns:
        The :class:`HandModel`; ``preshape`` holds the desired positions of the actuators
        (spread, f1, f2, f3 proximal) for the push-grasp preshape.
    """
    instance = plant.AddModelInstance(name)
    builder = _HandBuilder(plant, spec, layout, instance, material)
    hand = builder.build()
    gains = PdControllerGains(p=pd_gains[0], d=pd_gains[1])
    for actuator in hand.actuators:
        actuator.set_controller_gains(gains)
    return hand


class _HandBuilder:
    """Builds the hand's bodies, joints, geometry and constraints, one finger at a time."""

    def __init__(self, plant, spec, layout, instance, material):
        self.plant = plant
        self.spec = spec
        self.layout = layout
        self.instance = instance
        self.material = material
        self.patch_geometry: dict[str, GeometryId] = {}
        self.actuators: list[JointActuator] = []
        self.wanted = set(layout.patch_names)

    def build(self) -> HandModel:
        s = self.spec
        base = self._add_base()
        palm_frame = self.plant.AddFrame(FixedOffsetFrame("palm", base.body_frame(), s.X_BaseP))
        spread_joints = {}
        for finger, sign in (("f1", +1.0), ("f2", -1.0)):
            knuckle = self.plant.AddRigidBody(
                f"bh_{finger}_knuckle", self.instance,
                box_inertia(s.knuckle_mass, (s.link_width, s.knuckle_offset, 0.02),
                            RigidTransform([0, -s.knuckle_offset / 2, 0])),
            )
            self._collide(knuckle, RigidTransform([0, -s.knuckle_offset / 2, 0]),
                          Box(s.link_width, s.knuckle_offset, 0.02), f"{finger}_knuckle", None)
            X_BK = RigidTransform([sign * s.spread_offset, 0.0, s.finger_base_height])
            spread_joints[finger] = self._revolute(
                f"bh_{finger}_spread", base, knuckle, X_BK, [0.0, 0.0, sign], s.spread_limits
            )
            self._add_finger(finger, knuckle, s.finger_base_pose(finger))
        self._add_finger("f3", base, s.finger_base_pose("f3"))
        self.plant.AddCouplerConstraint(spread_joints["f2"], spread_joints["f1"], 1.0, 0.0)
        self.actuators.insert(
            0, self.plant.AddJointActuator("bh_spread", spread_joints["f1"], 5.0)
        )
        missing = self.wanted - set(self.patch_geometry)
        if missing:
            raise RuntimeError(f"tactile layout patches not built: {sorted(missing)}")
        preshape = np.array([s.preshape_spread] + [s.preshape_proximal] * 3)
        return HandModel(self.instance, base, palm_frame, self.patch_geometry,
                         self.actuators, preshape)

    def _add_base(self) -> RigidBody:
        s = self.spec
        body_height = s.palm_surface_height - s.pad_thickness
        X_palm_body = RigidTransform([0, 0, body_height / 2])
        inertia = cylinder_inertia(s.palm_mass, s.palm_radius, body_height, X_palm_body)
        inertia += cylinder_inertia(s.ft_mass, s.ft_radius, s.ft_thickness,
                                    RigidTransform([0, 0, -s.ft_thickness / 2]))
        base = self.plant.AddRigidBody("bh_base", self.instance, inertia)
        self._collide(base, X_palm_body, Cylinder(s.palm_radius, body_height), "palm_body", None)
        self._collide(base, RigidTransform([0, 0, -s.ft_thickness / 2]),
                      Cylinder(s.ft_radius, s.ft_thickness), "ft_sensor", None)
        # F3's fixed knuckle housing.
        self._collide(base, RigidTransform([0, s.knuckle_offset, s.finger_base_height]),
                      Box(s.link_width, 0.02, 0.02), "f3_knuckle", None)
        # Palm pad, split into strips along y (towards F3).
        pad_x, pad_y = s.pad_size
        z = s.palm_surface_height - s.pad_thickness / 2
        strips = self.layout.palm_strips
        if strips == 0:
            self._collide(base, RigidTransform([0, 0, z]), Box(pad_x, pad_y, s.pad_thickness),
                          "palm_pad", None)
        for i in range(strips):
            width = pad_y / strips
            y = -pad_y / 2 + (i + 0.5) * width
            self._collide(base, RigidTransform([0, y, z]), Box(pad_x, width, s.pad_thickness),
                          f"palm_{i}", f"palm_{i}")
        return base

    def _add_finger(self, finger: str, parent: RigidBody, X_PJ: RigidTransform) -> None:
        s = self.spec
        w, t = s.link_width, s.link_thickness
        sensing = finger in self.layout.fingers
        proximal = self.plant.AddRigidBody(
            f"bh_{finger}_proximal", self.instance,
            box_inertia(s.proximal_mass, (w, t, s.proximal_length),
                        RigidTransform([0, 0, s.proximal_length / 2])),
        )
        proximal_joint = self._revolute(
            f"bh_{finger}_proximal", parent, proximal, X_PJ, CLOSE_AXIS, s.proximal_limits
        )
        self._link_halves(proximal, finger, "proximal", 0.0, s.proximal_length,
                          self.layout.proximal_inner_segments if sensing else 0)
        reach = s.distal_reach
        distal = self.plant.AddRigidBody(
            f"bh_{finger}_distal", self.instance,
            box_inertia(s.distal_mass, (w, t, reach), RigidTransform([0, 0, reach / 2])),
        )
        X_PD = RigidTransform(RotationMatrix.MakeXRotation(-s.distal_offset),
                              [0, 0, s.proximal_length])
        distal_joint = self._revolute(
            f"bh_{finger}_distal", proximal, distal, X_PD, CLOSE_AXIS, s.distal_limits
        )
        tip = sensing and self.layout.fingertips
        body_end = reach - s.tip_length if tip else reach
        self._link_halves(distal, finger, "distal", 0.0, body_end,
                          self.layout.distal_inner_segments if sensing else 0,
                          outer_patch=sensing and self.layout.distal_outer)
        if tip:
            self._collide(distal, RigidTransform([0, 0, reach - s.tip_length / 2]),
                          Box(w, t, s.tip_length), f"{finger}_tip", f"{finger}_tip")
        self.plant.AddCouplerConstraint(distal_joint, proximal_joint, s.distal_coupling, 0.0)
        self.actuators.append(
            self.plant.AddJointActuator(f"bh_{finger}_proximal", proximal_joint, 5.0)
        )

    def _link_halves(self, body, finger, link, z0, z1, segments, *,
                     outer_patch: bool = False) -> None:
        """Cover a finger link (z in [z0, z1]) with an outer half (a patch named
        ``<finger>_<link>_outer`` when ``outer_patch``, else non-sensing) and an inner half
        split into ``segments`` patches (one non-sensing box when 0)."""
        w, t = self.spec.link_width, self.spec.link_thickness
        length = z1 - z0
        outer = f"{finger}_{link}_outer"
        self._collide(body, RigidTransform([0, -t / 4, (z0 + z1) / 2]), Box(w, t / 2, length),
                      outer, outer if outer_patch else None)
        if segments == 0:
            self._collide(body, RigidTransform([0, t / 4, (z0 + z1) / 2]),
                          Box(w, t / 2, length), f"{finger}_{link}_inner", None)
        for i in range(segments):
            seg = length / segments
            name = f"{finger}_{link}_{i}"
            self._collide(body, RigidTransform([0, t / 4, z0 + (i + 0.5) * seg]),
                          Box(w, t / 2, seg), name, name)

    def _collide(self, body, X_BG, shape, name, patch: str | None) -> None:
        geometry = add_geometry(self.plant, body, X_BG, shape, name, self.material,
                                SENSOR_RGBA if patch else HAND_RGBA)
        if patch is not None:
            self.patch_geometry[patch] = geometry

    def _revolute(self, name, parent, child, X_PF, axis, limits) -> RevoluteJoint:
        frame = self.plant.AddFrame(FixedOffsetFrame(f"{name}_parent", parent.body_frame(), X_PF))
        return self.plant.AddJoint(RevoluteJoint(
            name, frame, child.body_frame(), np.asarray(axis, dtype=float),
            limits[0], limits[1], 0.01,
        ))
