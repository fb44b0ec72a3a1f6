"""The pusher-slider rig's sensors as pure functions of the world's state (seed 003 sec.
V-A): per-rod force with noise, rod positions from kinematics with noise, and the AprilTag
camera with its calibration bias, noise and geometric occlusion.

The Drake systems in ``diagrams/`` call these; so can anything that has the true state.
"""

from __future__ import annotations

import numpy as np

from models.pose import wrap_angle
from models.pusher.occlusion import tag_corners, tag_visible
from models.pusher.rig import PusherSliderRig, occluders


def rod_positions(rig: PusherSliderRig, carriage: np.ndarray) -> np.ndarray:
    """(2, 2) the rods' centres (m, world) for the carriage pose (x, y, yaw)."""
    c, s = np.cos(carriage[2]), np.sin(carriage[2])
    return rig.pusher_offsets() @ np.array([[c, s], [-s, c]]) + carriage[:2]


def sense_forces(rig: PusherSliderRig, carriage: np.ndarray, forces: np.ndarray, *,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """One force-sensor sample.

    Args:
        carriage: (3,) the carriage pose. forces: (2, 2) the rods' true forces on the
        object (N, world).

    Returns:
        (rods (2, 2) m, forces (2, 2) N), each with the sensor's noise.
    """
    sensor = rig.force_sensor
    rods = rod_positions(rig, carriage) + rng.normal(0.0, sensor.position_noise_m, (2, 2))
    return rods, forces + rng.normal(0.0, sensor.noise_n, (2, 2))


class Camera:
    """The pose camera: visible when every tag corner is in sight; then the true pose
    plus the rig's fixed bias and per-frame noise.

    Args:
        rig: the rig (camera spec, occluding parts).
        object_height_m: the object's thickness (the tag sits on its top face).
    """

    def __init__(self, rig: PusherSliderRig, object_height_m: float):
        self.rig = rig
        self.height = object_height_m
        self.cylinders, self.boxes = occluders(rig)
        cam = rig.camera
        self.position = np.array(cam.position_m)
        self.bias = np.array([*cam.bias_m, np.deg2rad(cam.bias_deg)])
        self.sigma = np.array([cam.noise_m, cam.noise_m, np.deg2rad(cam.noise_deg)])

    def visible(self, truth: np.ndarray, carriage: np.ndarray) -> bool:
        corners = tag_corners(truth, self.rig.camera.tag_size_m, self.height)
        return tag_visible(self.position, corners, carriage, self.cylinders, self.boxes,
                           self.rig.pusher_clearance_m)

    def measure(self, truth: np.ndarray, carriage: np.ndarray, *,
                rng: np.random.Generator) -> np.ndarray | None:
        """(3,) a measured pose, or ``None`` when the tag is hidden."""
        if not self.visible(truth, carriage):
            return None
        pose = truth + self.bias + rng.normal(0.0, 1.0, 3) * self.sigma
        pose[2] = float(wrap_angle(pose[2]))
        return pose
