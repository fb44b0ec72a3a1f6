"""HERB's WAM arm with the BarrettHand, mounted as on HERB, in a ``MultibodyPlant``.

The WAM comes from ``models/assets/wam7.sdf`` (bodies ``wam_base``, ``wam1`` ... ``wam7``,
body frames = DH frames). The mount (``models/assets/herb.yaml``) puts the shoulder at
HERB's height with J1 pointing forward. The hand's ``bh_base`` is welded to ``wam7`` through
the wrist force/torque sensor (its thickness), so the ``palm`` frame is
``d7 + ft + palm_surface_height`` (0.151 m) past the wrist centre.

The robot is gravity-compensated: gravity is disabled on the arm and hand model instances,
which models the WAM's gravity-compensating controller exactly and leaves the implicit PD
controllers (stiff, stable at large time steps) to track the commanded joint trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains

from models.config import ASSETS_DIR, Fields
from models.herb.scene import ARMS, PlanarPose

WAM_SDF = ASSETS_DIR / "wam7.sdf"
WAM_BASE_TO_SHOULDER_M = np.array([0.22, 0.14, 0.346])
NUM_ARM_JOINTS = 7
#: Implicit PD gains of the arm joints: kp (N m/rad), kd (N m s/rad). With them the palm's
#: final tracking error in the demo push is 0.13 mm (``palm_final_error_m`` in the summary;
#: the smoke test bounds it at 2 mm).
ARM_PD_GAINS = (2000.0, 100.0)

#: Orientation of the palm frame P relative to the planar hand frame H (x forward in the
#: table plane, y left, z up): the palm faces forward (z_P = x_H), F3 is on the left
#: (y_P = y_H), and the F1/F2 spread axis x_P points down.
R_HP = RotationMatrix.MakeYRotation(np.pi / 2)


@dataclass(frozen=True)
class HerbMount:
    """Where a WAM sits on HERB (m, rad); see ``models/assets/herb.yaml``."""

    shoulder_height_m: float
    shoulder_lateral_offset_m: float
    shoulder_forward_offset_m: float
    base_roll: dict[str, float]
    home: dict[str, np.ndarray]

    @staticmethod
    def load(path: str | Path | None = None) -> HerbMount:
        fields = Fields.from_file(Path(path) if path else ASSETS_DIR / "herb.yaml")
        roll_f, home_f = fields.sub("base_roll_about_j1"), fields.sub("home")
        mount = HerbMount(
            shoulder_height_m=fields.number("shoulder_height", min=0.0, max=3.0),
            shoulder_lateral_offset_m=fields.number("shoulder_lateral_offset", min=0.0, max=1.0),
            shoulder_forward_offset_m=fields.number("shoulder_forward_offset", min=-1.0, max=1.0),
            base_roll={arm: roll_f.number(arm, min=-np.pi, max=np.pi) for arm in ARMS},
            home={arm: np.array(home_f.vector(arm, NUM_ARM_JOINTS)) for arm in ARMS},
        )
        for sub in (roll_f, home_f, fields):
            sub.done()
        return mount

    def shoulder_position(self, arm: str) -> np.ndarray:
        """World position (m) of the arm's shoulder (DH frame 0 origin)."""
        side = -1.0 if arm == "right" else 1.0
        return np.array([self.shoulder_forward_offset_m, side * self.shoulder_lateral_offset_m,
                         self.shoulder_height_m])

    def X_W_base(self, arm: str) -> RigidTransform:
        """World pose of ``wam_base``: J1 (base z) forward, rolled about J1 per the mount."""
        R = RotationMatrix.MakeYRotation(np.pi / 2) @ RotationMatrix.MakeZRotation(
            self.base_roll[arm])
        return RigidTransform(R, self.shoulder_position(arm) - R @ WAM_BASE_TO_SHOULDER_M)


def add_wam(
    plant: MultibodyPlant, mount: HerbMount, arm: str, *, pd_gains=ARM_PD_GAINS
) -> ModelInstanceIndex:
    """Parse the WAM into ``plant``, weld its base on HERB, give its actuators PD gains."""
    instance = Parser(plant, f"wam_{arm}").AddModels(WAM_SDF)[0]
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("wam_base", instance),
                     mount.X_W_base(arm))
    gains = PdControllerGains(p=pd_gains[0], d=pd_gains[1])
    for k in range(1, NUM_ARM_JOINTS + 1):
        actuator = plant.GetJointActuatorByName(f"wam_j{k}", instance)
        plant.get_mutable_joint_actuator(actuator.index()).set_controller_gains(gains)
    return instance


def X_W_palm(pose: PlanarPose | np.ndarray, palm_height_m: float) -> RigidTransform:
    """World pose of the palm frame for a planar hand pose (thesis eq. 7.1).

    Args:
        pose: planar hand pose (x m, y m, theta rad); theta is the push direction.
        palm_height_m: world height (m) of the palm frame (table top + hand height).
    """
    x, y, theta = pose.as_array() if isinstance(pose, PlanarPose) else np.asarray(pose)
    return RigidTransform(RotationMatrix.MakeZRotation(theta) @ R_HP, [x, y, palm_height_m])


def planar_palm_pose(X_W_palm: RigidTransform) -> np.ndarray:
    """The planar hand pose (x m, y m, theta rad) of a palm frame's world pose: its
    position in the plane and the heading of the palm's normal (z_P), the push direction;
    the inverse of :func:`X_W_palm` for poses at the pushing height."""
    p, z_P = X_W_palm.translation(), X_W_palm.rotation().col(2)
    return np.array([p[0], p[1], np.arctan2(z_P[1], z_P[0])])
