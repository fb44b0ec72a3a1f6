"""Seed 003's rig as one Drake ``Diagram``, and a run of a pushing procedure through it.

The diagram: the pusher-slider plant (``models/pusher/rig.py``), the rig's sensors
(:class:`PusherSensors`), optionally the estimator (:class:`VisuoTactileEstimator`), and
optionally Meshcat: the plant's illustration plus the estimate (red) and the camera's pose
(green) as outlines.

A run advances the diagram one force-sensor period at a time; before each period it sets
the carriage's desired state (the plant's PD input) from the procedure's waypoints. Each
stroke is planned when the previous one ends, from the object's true pose then
(:mod:`models.pusher.procedure`). After each period the newest sensor sample is recorded into
a :class:`PushLog`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial
from tqdm import tqdm

from diagrams.pusher.systems import (
    PoseOutlines,
    PusherSensors,
    VisuoTactileEstimator,
    unpack_force_sample,
)
from estimation.pushing.noise import PushingNoise
from estimation.pushing.smoother import SmootherSettings, recommended_settings
from models.objects import ObjectSpec
from models.pose import transform_to_planar
from models.pusher.log import PushLog
from models.pusher.procedure import Stroke, stroke_waypoints
from models.pusher.rig import PusherSliderRig, PusherSliderWorld, add_pusher_slider

#: The in-loop estimator's default: :func:`recommended_settings` at 200 steps.
RECOMMENDED = recommended_settings()
#: Plant step (s). Steel (1e8 Pa) against rigid rods needs a short step; 2 ms gives two
#: steps per force sample.
DEFAULT_TIME_STEP_S = 0.002


@dataclass
class PusherSliderDiagram:
    """A built diagram and handles to its parts (``estimator`` is ``None`` without one)."""

    diagram: Diagram
    plant: MultibodyPlant
    world: PusherSliderWorld
    sensors: PusherSensors
    estimator: VisuoTactileEstimator | None


def build_pusher_slider_diagram(rig: PusherSliderRig, object_spec: ObjectSpec, *,
                                seed: int = 0, time_step_s: float = DEFAULT_TIME_STEP_S,
                                estimator_noise: PushingNoise | None = None,
                                estimator_settings: SmootherSettings = RECOMMENDED,
                                meshcat: Meshcat | None = None) -> PusherSliderDiagram:
    """Plant, sensors, and (when ``estimator_noise`` is given) the estimator; Meshcat
    drawing when ``meshcat`` is given."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=time_step_s, contact_model="hydroelastic_with_fallback",
        discrete_contact_approximation="lagged"), builder)
    world = add_pusher_slider(plant, rig, object_spec)
    plant.Finalize()
    sensors = builder.AddSystem(PusherSensors(world, plant, seed=seed))
    builder.Connect(plant.get_contact_results_output_port(),
                    sensors.GetInputPort("contact_results"))
    builder.Connect(plant.get_body_poses_output_port(), sensors.GetInputPort("body_poses"))
    builder.Connect(plant.get_state_output_port(world.carriage),
                    sensors.GetInputPort("carriage_state"))
    estimator = None
    if estimator_noise is not None:
        estimator = builder.AddSystem(VisuoTactileEstimator(
            object_spec.footprint(), estimator_noise, rod_radius_m=rig.pusher_radius_m,
            contact_threshold_n=rig.force_sensor.contact_threshold_n,
            settings=estimator_settings))
        builder.Connect(sensors.GetOutputPort("force_sample"),
                        estimator.GetInputPort("force_sample"))
        builder.Connect(sensors.GetOutputPort("camera"), estimator.GetInputPort("camera"))
    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat,
                                       MeshcatVisualizerParams(role=Role.kIllustration))
        if estimator is not None:
            outlines = builder.AddSystem(PoseOutlines(meshcat, object_spec.footprint(),
                                                      height_m=object_spec.height_m + 0.002))
            builder.Connect(estimator.GetOutputPort("estimate"),
                            outlines.GetInputPort("estimate"))
            builder.Connect(sensors.GetOutputPort("camera"), outlines.GetInputPort("camera"))
    return PusherSliderDiagram(builder.Build(), plant, world, sensors, estimator)


@dataclass(frozen=True)
class PushRun:
    """A simulated run.

    Attributes:
        log: the sensors' record.
        estimates: (M, 4) the estimator's output at its rate: t (s), x, y, theta; empty
            without an estimator.
        occluded_fraction: camera frames with the tag hidden.
        contact_fraction: force samples with a rod in contact.
        update_ms: (U,) the estimator's per-update wall times (ms); empty without one.
    """

    log: PushLog
    estimates: np.ndarray
    occluded_fraction: float
    contact_fraction: float
    update_ms: np.ndarray


def simulate_push(rig: PusherSliderRig, object_spec: ObjectSpec, procedure: list[Stroke], *,
                  seed: int = 0, object_name: str = "", initial_pose: np.ndarray | None = None,
                  time_step_s: float = DEFAULT_TIME_STEP_S,
                  estimator_noise: PushingNoise | None = None,
                  estimator_settings: SmootherSettings = RECOMMENDED,
                  meshcat: Meshcat | None = None, progress: bool = False) -> PushRun:
    """Run ``procedure`` on ``object_spec`` and record the sensors (and the estimator).

    Args:
        rig: the rig (surface, sensors, camera).
        object_spec: the pushed object.
        procedure: the strokes, in order.
        seed: the sensors' noise seed.
        object_name: what the log calls the object (a built-in name or a path).
        initial_pose: (3,) the object's starting pose (default: the origin).
        time_step_s: the plant's step (s).
        estimator_noise: run the estimator in the loop with these covariances.
        estimator_settings: its settings.
        meshcat: draw the run there and record it (publish the recording at the end).
        progress: show a progress bar (one tick per stroke).
    """
    built = build_pusher_slider_diagram(rig, object_spec, seed=seed, time_step_s=time_step_s,
                                        estimator_noise=estimator_noise,
                                        estimator_settings=estimator_settings, meshcat=meshcat)
    plant, world = built.plant, built.world
    simulator = Simulator(built.diagram)
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    pose0 = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, dtype=float)
    plant.SetFreeBodyPose(plant_context, world.object_body, world.X_WO_initial(pose0))
    footprint = object_spec.footprint()
    reach = float(np.max(np.linalg.norm(footprint, axis=1)))
    carriage = np.array([pose0[0] - reach - 0.08, pose0[1], 0.0])
    plant.SetPositions(plant_context, world.carriage, carriage)
    desired = plant.get_desired_state_input_port(world.carriage)
    desired.FixValue(plant_context, np.concatenate([carriage, np.zeros(3)]))

    sensors_context = built.sensors.GetMyContextFromRoot(context)
    force_port = built.sensors.GetOutputPort("force_sample")
    camera_port = built.sensors.GetOutputPort("camera")
    estimator_context = (built.estimator.GetMyContextFromRoot(context)
                         if built.estimator is not None else None)
    period = built.sensors.force_period_s
    rows, estimates = [], []
    last_sample_t, last_frame_t = -1.0, -1.0
    frames = occluded = 0
    if meshcat is not None:
        # look at the object from the front-right and above, 45 cm away
        meshcat.SetCameraPose(pose0 + np.array([0.30, -0.35, 0.30]),
                              np.array([pose0[0], pose0[1], 0.0]))
        meshcat.StartRecording(frames_per_second=30.0)
    t_end = 0.0
    for stroke in tqdm(procedure, desc="simulating push", unit="stroke", disable=not progress):
        object_pose = transform_to_planar(plant.EvalBodyPoseInWorld(plant_context,
                                                                    world.object_body))
        durations, poses = stroke_waypoints(
            stroke, object_pose, footprint, carriage, spacing_m=rig.pusher_spacing_m,
            rod_radius_m=rig.pusher_radius_m, push_speed=rig.push_speed_m_per_s,
            transit_speed=rig.transit_speed_m_per_s)
        times = t_end + np.concatenate([[0.0], np.cumsum(durations)])
        trajectory = PiecewisePolynomial.FirstOrderHold(times, np.vstack([carriage, poses]).T)
        carriage, t_end = poses[-1], float(times[-1])
        t = simulator.get_context().get_time()
        while t + period <= t_end + 1e-9:
            t += period
            desired.FixValue(plant_context, np.concatenate([
                trajectory.value(t).ravel(), trajectory.EvalDerivative(t, 1).ravel()]))
            simulator.AdvanceTo(t)
            sample = force_port.Eval(sensors_context)
            camera = camera_port.Eval(sensors_context)
            if sample[0] <= last_sample_t:
                continue
            last_sample_t = sample[0]
            fresh = camera[0] > last_frame_t
            if fresh:
                last_frame_t = camera[0]
                frames += 1
                occluded += int(camera[4] < 0.5)
            rows.append((sample.copy(), camera.copy(), fresh and camera[4] > 0.5))
            if estimator_context is not None:
                estimates.append([t, *built.estimator.GetOutputPort("estimate")
                                  .Eval(estimator_context)])
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    log = _log(rows, rig, object_name or object_spec.name)
    update_ms = np.zeros(0)
    if estimator_context is not None:
        smoother = built.estimator.smoother(estimator_context)
        if smoother is not None:
            update_ms = np.array(smoother.update_seconds) * 1e3
    return PushRun(log, np.array(estimates).reshape(-1, 4), occluded / max(1, frames),
                   float(log.contacts().any(axis=1).mean()), update_ms)


def _log(rows, rig: PusherSliderRig, object_name: str) -> PushLog:
    n = len(rows)
    t, rods, forces = np.empty(n), np.empty((n, 2, 2)), np.empty((n, 2, 2))
    truth, carriage = np.empty((n, 3)), np.empty((n, 3))
    vision_ok, vision = np.zeros(n, dtype=bool), np.full((n, 3), np.nan)
    for i, (sample, camera, new_frame) in enumerate(rows):
        t[i], rods[i], forces[i], truth[i], carriage[i] = unpack_force_sample(sample)
        if new_frame:
            vision_ok[i] = True
            vision[i] = camera[1:4]
    return PushLog(t, rods, forces, vision_ok, vision, truth, carriage, object_name,
                   rig.pusher_radius_m, rig.force_sensor.contact_threshold_n, rig.surface)
