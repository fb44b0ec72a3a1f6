"""Drawing the hand-relative belief in Meshcat, live and into the recording.

What a user sees (thesis Fig. 6.8's ingredients): faint outlines of a subset of the
particles, the belief mean (a bold outline), the goal region (a rectangle that moves with
the hand), and one marker per binary sensor, lit while it reads contact. The true object
is the plant's own geometry.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba, Sphere
from pydrake.systems.framework import EventStatus, LeafSystem

from estimation.particles.belief import ParticleBelief
from models.pose import planar_to_transform
from models.se2 import compose

PARTICLE_RGBA = Rgba(0.85, 0.35, 0.1, 0.35)
MEAN_RGBA = Rgba(0.9, 0.1, 0.1, 1.0)
GOAL_PALETTE = ((0.1, 0.7, 0.2), (0.8, 0.15, 0.75), (0.1, 0.6, 0.9), (0.15, 0.15, 0.15))
"""Goal-region colours (green, magenta, sky blue, near-black); the drawer takes the one
farthest from the object's colour, so the goal never looks like the object."""
SENSOR_OFF_RGBA = Rgba(0.6, 0.6, 0.6, 0.5)
SENSOR_ON_RGBA = Rgba(1.0, 0.9, 0.0, 1.0)


def goal_rgba(object_rgba) -> Rgba:
    """The :data:`GOAL_PALETTE` colour farthest (in RGB) from ``object_rgba``."""
    rgb = np.asarray(object_rgba, dtype=float)[:3]
    far = max(GOAL_PALETTE, key=lambda c: float(np.sum((np.asarray(c) - rgb) ** 2)))
    return Rgba(*far, 1.0)


def _loop(points_2d: np.ndarray, z: float) -> np.ndarray:
    """(3, V + 1) a closed 3-D polyline of (V, 2) points at height ``z``."""
    loop = np.vstack([points_2d, points_2d[:1]])
    return np.vstack([loop.T, np.full(len(loop), z)])


class BeliefDrawer(LeafSystem):
    """Input ports: ``belief`` (abstract, hand frame), ``palm_pose`` (3),
    ``sensor_contact`` (S).

    Args:
        meshcat: where to draw.
        outline: (V, 2) the object's outline about its centre (m).
        object_rgba: the object's colour (the goal is drawn in a contrasting one).
        goal: (2, 2) [[x_lo, y_lo], [x_hi, y_hi]] the goal region in the hand frame (m).
        sensor_points: (S, 2) where to mark each sensor, hand frame (m).
        height_m: drawing height (m): just above the object's top, so that the belief is
            seen from above rather than hidden under the object.
        particles: how many particles to outline.
        period_s: drawing period (s).
    """

    def __init__(self, meshcat: Meshcat, outline: np.ndarray, goal: np.ndarray,
                 sensor_points: np.ndarray, initial: ParticleBelief, *, height_m: float,
                 object_rgba: tuple[float, float, float, float],
                 particles: int = 60, period_s: float = 0.1):
        super().__init__()
        self._meshcat = meshcat
        self._height = height_m
        self._count = particles
        self._particle_paths = [f"/belief/particles/{i}" for i in range(particles)]
        for path in self._particle_paths:
            meshcat.SetLine(path, _loop(outline, 0.0), 1.0, PARTICLE_RGBA)
        meshcat.SetLine("/belief/mean", _loop(outline, 0.0), 4.0, MEAN_RGBA)
        (x0, y0), (x1, y1) = goal
        corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        meshcat.SetLine("/belief/goal", _loop(corners, 0.0), 3.0, goal_rgba(object_rgba))
        self._sensor_points = np.asarray(sensor_points, dtype=float)
        for i in range(len(self._sensor_points)):
            for on, rgba in ((False, SENSOR_OFF_RGBA), (True, SENSOR_ON_RGBA)):
                meshcat.SetObject(self._sensor_path(i, on), Sphere(0.008), rgba)
        self._belief = self.DeclareAbstractInputPort("belief", AbstractValue.Make(initial))
        self._palm = self.DeclareVectorInputPort("palm_pose", 3)
        self._readings = self.DeclareVectorInputPort("sensor_contact",
                                                     len(self._sensor_points))
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._draw)
        self.DeclareForcedPublishEvent(self._draw)

    @staticmethod
    def _sensor_path(i: int, on: bool) -> str:
        return f"/belief/sensors/{i}/{'on' if on else 'off'}"

    def _draw(self, context) -> EventStatus:
        t = context.get_time()
        palm = self._palm.Eval(context)
        belief: ParticleBelief = self._belief.Eval(context)
        states = np.asarray(belief.states)
        shown = states[np.linspace(0, len(states) - 1, self._count).astype(int)]
        z, meshcat = self._height, self._meshcat
        for path, pose in zip(self._particle_paths, compose(palm, shown), strict=True):
            meshcat.SetTransform(path, planar_to_transform(*pose, z), t)
        meshcat.SetTransform("/belief/mean",
                             planar_to_transform(*compose(palm, belief.mean()), z + 0.001), t)
        meshcat.SetTransform("/belief/goal", planar_to_transform(*palm, z), t)
        readings = self._readings.Eval(context) > 0.5
        points = compose(palm, np.column_stack([self._sensor_points,
                                                np.zeros(len(self._sensor_points))]))
        for i, (point, on) in enumerate(zip(points, readings, strict=True)):
            X = planar_to_transform(*point, z + 0.01)
            meshcat.SetTransform(self._sensor_path(i, True), X, t)
            meshcat.SetTransform(self._sensor_path(i, False), X, t)
            meshcat.SetProperty(self._sensor_path(i, True), "visible", bool(on), t)
            meshcat.SetProperty(self._sensor_path(i, False), "visible", not bool(on), t)
        return EventStatus.Succeeded()
