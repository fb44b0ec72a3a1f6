"""Simulating seed 003's rig in Drake and recording what its sensors see (a :class:`PushLog`).

The diagram is the pusher-slider plant (``models/pusher_slider.py``) and, optionally, a
Meshcat visualiser. A Python loop advances it one force-sensor period at a time (4 ms at
250 Hz): it sets the carriage's desired state from the procedure's waypoints, then reads

- each rod's force on the object from the plant's contact results, plus noise;
- the rods' positions from the carriage's joints, plus noise;
- a camera pose at the camera's rate when every tag corner is in sight
  (:mod:`models.camera_occlusion`), with the rig's fixed calibration bias and noise;
- the object's true pose.

Each stroke is planned when the previous one ends, from the object's true pose then
(:mod:`models.push_procedure`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial
from tqdm import tqdm

from models.camera_occlusion import tag_corners, tag_visible
from models.objects import ObjectSpec
from models.pose import transform_to_planar, wrap_angle
from models.push_log import PushLog
from models.push_procedure import Stroke, stroke_waypoints
from models.pusher_slider import PusherSliderRig, PusherSliderWorld, add_pusher_slider, occluders

#: Plant step (s). Steel (1e8 Pa) against rigid rods needs a short step; 2 ms gives two
#: steps per force sample.
DEFAULT_TIME_STEP_S = 0.002


@dataclass(frozen=True)
class PushRun:
    """A simulated run: its log and the Meshcat recording, if one was made."""

    log: PushLog
    occluded_fraction: float
    contact_fraction: float


def simulate_push(rig: PusherSliderRig, object_spec: ObjectSpec, procedure: list[Stroke], *,
                  rng: np.random.Generator, object_name: str = "",
                  initial_pose: np.ndarray | None = None,
                  time_step_s: float = DEFAULT_TIME_STEP_S, meshcat: Meshcat | None = None,
                  progress: bool = False) -> PushRun:
    """Run ``procedure`` on ``object_spec`` and record the sensors.

    Args:
        rig: the rig (surface, sensors, camera).
        object_spec: the pushed object.
        procedure: the strokes, in order.
        rng: draws the sensor noise.
        object_name: what the log calls the object (a built-in name or a path).
        initial_pose: (3,) the object's starting pose (default: the origin).
        time_step_s: the plant's step (s).
        meshcat: when given, the run is drawn there and recorded (``StartRecording``).
        progress: show a progress bar.
    """
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=time_step_s, contact_model="hydroelastic_with_fallback",
        discrete_contact_approximation="lagged"), builder)
    world = add_pusher_slider(plant, rig, object_spec)
    plant.Finalize()
    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat,
                                       MeshcatVisualizerParams(role=Role.kIllustration))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    pose0 = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, dtype=float)
    plant.SetFreeBodyPose(plant_context, world.object_body, world.X_WO_initial(pose0))
    footprint = object_spec.footprint()
    reach = float(np.max(np.linalg.norm(footprint, axis=1)))
    carriage = np.array([pose0[0] - reach - 0.08, pose0[1], 0.0])
    plant.SetPositions(plant_context, world.carriage, carriage)
    desired = plant.get_desired_state_input_port(world.carriage)

    period = 1.0 / rig.force_sensor.rate_hz
    plans = _plan_all(world, procedure, footprint, plant, plant_context, carriage)
    recorder = _Recorder(rig, world, rng)
    if meshcat is not None:
        meshcat.StartRecording(frames_per_second=1.0 / (4 * period))
    bar = tqdm(total=None, desc="simulating push", unit="stroke", disable=not progress)
    t_end = 0.0
    for stroke_index, make_plan in enumerate(plans):
        trajectory = make_plan(t_end)
        t_end = trajectory.end_time()
        t = simulator.get_context().get_time()
        while t + period <= t_end + 1e-9:
            t += period
            q = trajectory.value(t).ravel()
            v = trajectory.EvalDerivative(t, 1).ravel()
            desired.FixValue(plant_context, np.concatenate([q, v]))
            simulator.AdvanceTo(t)
            recorder.sample(t, plant, plant_context)
        bar.update(1)
        bar.set_postfix(stroke=stroke_index + 1)
    bar.close()
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    log = recorder.log(object_name or object_spec.name)
    return PushRun(log, recorder.occluded / max(1, recorder.frames),
                   float(log.contacts().any(axis=1).mean()))


def _plan_all(world: PusherSliderWorld, procedure, footprint, plant, plant_context, carriage):
    """One closure per stroke; each plans from the true object pose when it is called."""
    rig = world.rig
    state = {"carriage": carriage}

    def planner(stroke):
        def make(t_start):
            pose = transform_to_planar(plant.EvalBodyPoseInWorld(plant_context,
                                                                 world.object_body))
            durations, poses = stroke_waypoints(
                stroke, pose, footprint, state["carriage"], spacing_m=rig.pusher_spacing_m,
                rod_radius_m=rig.pusher_radius_m, push_speed=rig.push_speed_m_per_s,
                transit_speed=rig.transit_speed_m_per_s)
            times = t_start + np.concatenate([[0.0], np.cumsum(durations)])
            knots = np.vstack([state["carriage"], poses])
            state["carriage"] = poses[-1]
            return PiecewisePolynomial.FirstOrderHold(times, knots.T)
        return make

    return [planner(stroke) for stroke in procedure]


class _Recorder:
    """Turns plant states into sensor rows."""

    def __init__(self, rig: PusherSliderRig, world: PusherSliderWorld,
                 rng: np.random.Generator):
        self.rig, self.world, self.rng = rig, world, rng
        self.rows: list[np.ndarray] = []
        self.next_frame_t = 0.0
        self.frames = 0
        self.occluded = 0
        self.cylinders, self.boxes = occluders(rig)
        cam = rig.camera
        self.bias = np.array([*cam.bias_m, np.deg2rad(cam.bias_deg)])
        self.noise = np.array([cam.noise_m, cam.noise_m, np.deg2rad(cam.noise_deg)])

    def sample(self, t, plant, plant_context) -> None:
        rig, world = self.rig, self.world
        truth = transform_to_planar(plant.EvalBodyPoseInWorld(plant_context, world.object_body))
        carriage = plant.GetPositions(plant_context, world.carriage)
        c, s = np.cos(carriage[2]), np.sin(carriage[2])
        rods = rig.pusher_offsets() @ np.array([[c, s], [-s, c]]) + carriage[:2]
        forces = _rod_forces(plant, plant_context, world)
        sensor = rig.force_sensor
        rods_measured = rods + self.rng.normal(0.0, sensor.position_noise_m, rods.shape)
        forces_measured = forces + self.rng.normal(0.0, sensor.noise_n, forces.shape)
        vision_ok, vision = 0.0, np.full(3, np.nan)
        if t + 1e-9 >= self.next_frame_t:
            self.next_frame_t += 1.0 / rig.camera.rate_hz
            self.frames += 1
            corners = tag_corners(truth, rig.camera.tag_size_m, world.object_spec.height_m)
            if tag_visible(np.array(rig.camera.position_m), corners, carriage, self.cylinders,
                           self.boxes, rig.pusher_clearance_m):
                vision_ok = 1.0
                vision = truth + self.bias + self.rng.normal(0.0, 1.0, 3) * self.noise
                vision[2] = float(wrap_angle(vision[2]))
            else:
                self.occluded += 1
        self.rows.append(np.concatenate([[t], rods_measured.ravel(), forces_measured.ravel(),
                                         [vision_ok], vision, truth, carriage]))

    def log(self, object_name: str) -> PushLog:
        table = np.array(self.rows)
        rods = table[:, 1:5].reshape(-1, 2, 2)
        forces = table[:, 5:9].reshape(-1, 2, 2)
        return PushLog(table[:, 0], rods, forces, table[:, 9] > 0.5, table[:, 10:13],
                       table[:, 13:16], table[:, 16:19], object_name, self.rig.pusher_radius_m,
                       self.rig.force_sensor.contact_threshold_n, self.rig.surface)


def _rod_forces(plant, plant_context, world: PusherSliderWorld) -> np.ndarray:
    """(2, 2) each rod's force on the object in the world's xy (N), from the contact
    results (hydroelastic, and point pairs should a pair fall back to them)."""
    results = plant.get_contact_results_output_port().Eval(plant_context)
    forces = np.zeros((2, 2))
    rods = world.rod_geometries
    for i in range(results.num_hydroelastic_contacts()):
        info = results.hydroelastic_contact_info(i)
        surface = info.contact_surface()
        f = info.F_Ac_W().translational()[:2]  # on the body of geometry M
        for k, rod in enumerate(rods):
            if surface.id_M() == rod:
                forces[k] -= f  # M is the rod: the object feels the opposite
            elif surface.id_N() == rod:
                forces[k] += f
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        pair = info.point_pair()
        f = info.contact_force()[:2]  # on body B
        for k, rod in enumerate(rods):
            if pair.id_A == rod:
                forces[k] += f  # B is the other body (the object)
            elif pair.id_B == rod:
                forces[k] -= f
    return forces
