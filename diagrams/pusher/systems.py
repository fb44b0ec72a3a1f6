"""LeafSystems of the pusher-slider diagram (seed 003): the rig's sensors, the
visuo-tactile estimator, and the Meshcat drawing of the estimate and the camera's pose.

Each is a thin adapter over a pure core: :mod:`models.pusher.sensors` for the sensors,
:class:`estimation.pushing.smoother.VisuoTactileSmoother` for the estimator.

Port layouts (world frame, SI):

- ``force_sample`` (15): sample time (s); rod 0 x, y; rod 1 x, y (m); rod 0 fx, fy; rod 1
  fx, fy (N, force on the object); true object x, y, theta; carriage x, y, yaw.
- ``camera`` (5): frame time (s); x, y, theta; 1 if the tag was visible, else 0.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue, Value
from pydrake.geometry import Meshcat, Rgba
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactResults
from pydrake.systems.framework import EventStatus, LeafSystem

from diagrams.tactile_sensor import contact_pairs_by_patch
from estimation.pushing.noise import PushingNoise
from estimation.pushing.smoother import (
    SmootherSettings,
    VisuoTactileSmoother,
    recommended_settings,
)
from models.pose import planar_to_transform, transform_to_planar
from models.pusher.rig import PusherSliderWorld
from models.pusher.sensors import Camera, sense_forces

FORCE_SAMPLE_SIZE = 15
CAMERA_SIZE = 5


def unpack_force_sample(sample: np.ndarray):
    """(t, rods (2, 2), forces (2, 2), truth (3,), carriage (3,)) from a ``force_sample``."""
    return (float(sample[0]), sample[1:5].reshape(2, 2), sample[5:9].reshape(2, 2),
            sample[9:12], sample[12:15])


class PusherSensors(LeafSystem):
    """The rig's force sensors (with the rods' positions) and its pose camera, sampled
    into discrete state at their rates. The noise of sample k comes from
    ``np.random.default_rng([seed, stream, k])``: reproducible, never redrawn on
    re-evaluation.

    Input ports: ``contact_results`` (abstract), ``body_poses`` (the plant's, abstract),
    ``carriage_state`` (6: x, y, yaw and rates).
    Output ports: ``force_sample`` (15), ``camera`` (5); see the module docstring.
    """

    def __init__(self, world: PusherSliderWorld, plant, *, seed: int = 0):
        super().__init__()
        self.world = world
        rig = world.rig
        self._rods = {geometry: k for k, geometry in enumerate(world.rod_geometries)}
        self._object_index = int(world.object_body.index())
        self._camera = Camera(rig, world.object_spec.height_m)
        self._seed = seed
        self.force_period_s = 1.0 / rig.force_sensor.rate_hz
        self.camera_period_s = 1.0 / rig.camera.rate_hz
        self._contacts = self.DeclareAbstractInputPort("contact_results",
                                                       Value(ContactResults()))
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()] * plant.num_bodies()))
        self._carriage = self.DeclareVectorInputPort("carriage_state", 6)
        initial = np.full(FORCE_SAMPLE_SIZE, np.nan)
        initial[0] = -1.0
        self._force_state = self.DeclareDiscreteState(initial)
        self._camera_state = self.DeclareDiscreteState(np.array([-1.0, np.nan, np.nan,
                                                                 np.nan, 0.0]))
        self.DeclarePeriodicDiscreteUpdateEvent(self.force_period_s, 0.0, self._sample_forces)
        self.DeclarePeriodicDiscreteUpdateEvent(self.camera_period_s, 0.0, self._sample_camera)
        self.DeclareStateOutputPort("force_sample", self._force_state)
        self.DeclareStateOutputPort("camera", self._camera_state)

    def _truth_and_carriage(self, context):
        X_WO = self._poses.Eval(context)[self._object_index]
        return transform_to_planar(X_WO), self._carriage.Eval(context)[:3].copy()

    def _sample_forces(self, context, discrete_state) -> EventStatus:
        t = context.get_time()
        truth, carriage = self._truth_and_carriage(context)
        pair_rod, pair_force = contact_pairs_by_patch(self._contacts.Eval(context), self._rods)
        forces = np.zeros((2, 2))
        np.add.at(forces, pair_rod, -pair_force[:, :2])  # the object feels the opposite
        k = int(round(t / self.force_period_s))
        rods, measured = sense_forces(self.world.rig, carriage, forces,
                                      rng=np.random.default_rng([self._seed, 0, k]))
        discrete_state.set_value(int(self._force_state), np.concatenate(
            [[t], rods.ravel(), measured.ravel(), truth, carriage]))
        return EventStatus.Succeeded()

    def _sample_camera(self, context, discrete_state) -> EventStatus:
        t = context.get_time()
        truth, carriage = self._truth_and_carriage(context)
        k = int(round(t / self.camera_period_s))
        pose = self._camera.measure(truth, carriage,
                                    rng=np.random.default_rng([self._seed, 1, k]))
        value = (np.array([t, *pose, 1.0]) if pose is not None
                 else np.array([t, np.nan, np.nan, np.nan, 0.0]))
        discrete_state.set_value(int(self._camera_state), value)
        return EventStatus.Succeeded()


class _EstimatorMemory:
    """What the estimator system carries between updates (held in abstract state).

    A handle once started: GTSAM's iSAM2 cannot be copied, and Drake copies abstract state
    for every unrestricted update, so copies of a started memory share its one estimator
    (a context cloned mid-run shares it with the original). An unstarted memory copies
    to a fresh one, so every new context gets its own estimator.
    """

    def __init__(self):
        self.smoother: VisuoTactileSmoother | None = None
        self.last_frame_t = -np.inf

    def __deepcopy__(self, memo):
        return self if self.smoother is not None else _EstimatorMemory()


class VisuoTactileEstimator(LeafSystem):
    """Seed 003's estimator at a fixed rate (100 Hz by default).

    Each update takes the latest force sample and, if a camera frame arrived since the last
    update, its pose; it starts at the first camera pose. Contact is ``|f| >=
    contact_threshold_n``.

    Input ports: ``force_sample`` (15), ``camera`` (5).
    Output port: ``estimate`` (3): x, y, theta (nan until the first camera pose).

    Args:
        polygon: (V, 2) the object's outline (m). noise: the costs' covariances.
        settings: the smoother's settings (default: ``recommended_settings()``).
        rod_radius_m, contact_threshold_n: the rig's.
        period_s: update period (s).
    """

    def __init__(self, polygon: np.ndarray, noise: PushingNoise, *, rod_radius_m: float,
                 contact_threshold_n: float, settings: SmootherSettings | None = None,
                 period_s: float = 0.01):
        super().__init__()
        settings = settings or recommended_settings()
        self._make = lambda: VisuoTactileSmoother(polygon, noise, settings,
                                                  rod_radius_m=rod_radius_m)
        self._threshold = contact_threshold_n
        self._forces = self.DeclareVectorInputPort("force_sample", FORCE_SAMPLE_SIZE)
        self._camera = self.DeclareVectorInputPort("camera", CAMERA_SIZE)
        self._memory = self.DeclareAbstractState(AbstractValue.Make(_EstimatorMemory()))
        self._estimate = self.DeclareDiscreteState(np.full(3, np.nan))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)
        self.DeclareStateOutputPort("estimate", self._estimate)

    def smoother(self, context) -> VisuoTactileSmoother | None:
        """The smoother inside ``context`` (for its timings), or ``None`` before start."""
        return context.get_abstract_state(int(self._memory)).get_value().smoother

    def _update(self, context, state) -> EventStatus:
        memory = state.get_mutable_abstract_state(int(self._memory)).get_value()
        if memory.smoother is None:
            memory.smoother = self._make()
        t_force, rods, forces, _, _ = unpack_force_sample(self._forces.Eval(context))
        camera = self._camera.Eval(context)
        if t_force < 0:
            return EventStatus.DidNothing()
        contact = np.linalg.norm(forces, axis=1) >= self._threshold
        fresh = camera[4] > 0.5 and camera[0] > memory.last_frame_t
        vision = camera[1:4].copy() if fresh else None
        if fresh:
            memory.last_frame_t = camera[0]
        smoother = memory.smoother
        if not smoother.started:
            if vision is None:
                return EventStatus.DidNothing()
            smoother.start(vision)
            estimate = vision
        else:
            estimate = smoother.step(rods, forces, contact, vision)
        state.get_mutable_discrete_state(int(self._estimate)).SetFromVector(estimate)
        return EventStatus.Succeeded()


class PoseOutlines(LeafSystem):
    """Draws object outlines at planar poses in Meshcat (the estimate and the camera's
    pose), at the drawing rate and into any recording.

    Input ports: ``estimate`` (3), ``camera`` (5).

    Args:
        meshcat: where to draw. polygon: (V, 2) the outline (m). height_m: drawing
        height (m). period_s: drawing period (s).
    """

    def __init__(self, meshcat: Meshcat, polygon: np.ndarray, *, height_m: float,
                 period_s: float = 1.0 / 30):
        super().__init__()
        self._meshcat = meshcat
        loop = np.vstack([polygon, polygon[:1]])
        points = np.vstack([loop.T, np.full(len(loop), height_m)])
        self._paths = {"estimate": "/pusher/estimate", "camera": "/pusher/camera"}
        meshcat.SetLine(self._paths["estimate"], points, 4.0, Rgba(0.9, 0.1, 0.1, 1.0))
        meshcat.SetLine(self._paths["camera"], points, 2.0, Rgba(0.1, 0.7, 0.2, 1.0))
        self._estimate = self.DeclareVectorInputPort("estimate", 3)
        self._camera = self.DeclareVectorInputPort("camera", CAMERA_SIZE)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._draw)
        self.DeclareForcedPublishEvent(self._draw)

    def _draw(self, context) -> EventStatus:
        t = context.get_time()
        estimate = self._estimate.Eval(context)
        camera = self._camera.Eval(context)
        for name, pose, shown in (("estimate", estimate, np.all(np.isfinite(estimate))),
                                  ("camera", camera[1:4], camera[4] > 0.5)):
            path = self._paths[name]
            self._meshcat.SetProperty(path, "visible", bool(shown), t)
            if shown:
                self._meshcat.SetTransform(path, planar_to_transform(*pose), t)
        return EventStatus.Succeeded()
