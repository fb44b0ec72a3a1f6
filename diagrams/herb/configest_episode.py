"""The thesis' real-robot configuration-estimation experiment (sec. 5.5, Fig. 5.4b) as a
simulation in the HERB diagram.

HERB's arm follows a commanded joint trajectory through the plant's PD control and
touches a large box on the table; its encoders read the arm through a constant offset
(a cable drive's, ``dq ~ N(0, sd^2 I)``) plus noise; the tactile system (hydroelastic
contact on the distal links' patches, pooled per finger like HERB's strain gauges, with
the thesis' 10 % reading errors) reports contact. Two estimators run side by side on the
same readings: the CPF and MPF-Ball (n = 100 each: the MPF as 90 propagated and 10 dual
particles, phi = 0.1). Outputs: ``summary.json`` (joint error of each estimate, final and
mean), ``episode.npz`` (times, true, commanded and encoder configurations, readings and
each estimate, per update), ``joint_error.png`` (error over time, contact readings
marked) and, with Meshcat,
``replay.html`` (the arm, the ghost arms of MPF-Ball's particles, both means, lit fingers).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, MatrixGain, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from tqdm import tqdm

from diagrams.herb.configuration import ArmBeliefDrawer, ConfigurationEstimator, Encoders
from diagrams.herb.station import add_herb_plant, add_meshcat
from diagrams.tactile_sensor import TactileSensor
from estimation.configuration.history import check_dual_density, dual_ball_radius
from estimation.configuration.lift import check_dual_lift, make_dual_lift
from estimation.configuration.manifold import ProjectionManifold
from estimation.configuration.proprioception import check_proprioception
from estimation.particles.factory import make_filter
from models.arms.spec import ArmSpec
from models.arms.world import ArmWorld
from models.contact import SimulationConfig
from models.herb.scene import SceneSpec
from models.herb.tactile import SensorGroups, TactileLayout, TactileNoise
from models.pose import wrap_angle
from models.settings import check_ranges

ESTIMATORS = ("cpf", "mpf-ball")

OFFSET_STREAM = 3
"""The encoder offset is drawn from ``(seed, 3)``, a stream no sensor draws from."""


@dataclass(frozen=True)
class ConfigestEpisodeSettings:
    """One episode.

    Attributes:
        arm: the arm file (its scene, sensors, offsets and commanded trajectory).
        layout: the tactile layout whose patches, pooled per finger, are the sensors.
        particles: n of each estimator (thesis sec. 5.5: 100).
        dual_particles: the MPF's n_d (of ``particles``).
        mixing_rate: the MPF's phi.
        seconds_per_step: time per commanded step (s).
        estimator_period_s: how often encoders, tactile system and estimators update (s).
        process_noise_radius_rad: the estimators' motion noise per update (rad).
        ball_radius_rad: MPF-Ball's r_b (None: three kernel bandwidths, thesis sec. 5.2).
        constraints: what MPF-Ball's projected duals satisfy, ``active`` (eq. 5.1) or
            ``full`` (:mod:`estimation.configuration.projection`).
        dual_share: the MPF's split between its sets, ``fixed`` (Alg. 4.2), ``density`` or
            ``evidence``
            (:class:`estimation.particles.filters.ManifoldParticleFilter`).
        metric: MPF-Ball's balls and projection in ``joint`` space (sec. 5.2) or in the
            ``kernel`` bandwidths (:mod:`estimation.configuration.manifold`).
        dual_density: MPF-Ball's weights of its duals, the predicted particles' ``kernel``
            density (sec. 4.2.3) or the readings' exact ``history`` density
            (:mod:`estimation.configuration.history`, which also sets r_b).
        dual_lift: MPF-Ball's duals on the contact ``surface`` (sec. 5.2) or lifted along
            the ``normal`` to the commanded side (:mod:`estimation.configuration.lift`).
        proprioception: what both estimators take from the encoders, ``first`` or
            ``steps`` (:mod:`estimation.configuration.proprioception`).
        outlier_log_evidence: both estimators' outlier gate (None: none, the thesis;
            :class:`estimation.particles.filters.ConventionalParticleFilter`).
        tactile_error_rate: the tactile system's false-negative and in-contact
            false-positive rate (None: the arm file's ``sensor_error_rate``, which is also
            what the estimators assume).
        seed: seeds the offset, the encoder and tactile noise and the estimators.
        sim: the plant's time step and contact approximation.
    """

    arm: str = "wam_fingers"
    layout: str = "distal_links"
    particles: int = 100
    dual_particles: int = 10
    mixing_rate: float = 0.1
    seconds_per_step: float = 0.05
    estimator_period_s: float = 0.05
    process_noise_radius_rad: float = 0.01
    ball_radius_rad: float | None = None
    constraints: str = "active"
    dual_share: str = "fixed"
    metric: str = "joint"
    dual_density: str = "kernel"
    dual_lift: str = "surface"
    proprioception: str = "first"
    outlier_log_evidence: float | None = None
    tactile_error_rate: float | None = None
    seed: int = 0
    sim: SimulationConfig = field(default_factory=SimulationConfig)

    def __post_init__(self):
        """Raise ValueError naming the field (and its ``configest run`` option) out of
        range."""
        if self.particles < 2 or not 1 <= self.dual_particles < self.particles:
            raise ValueError(f"dual_particles (--dual-particles) must be in [1, particles), "
                             f"got {self.dual_particles} with {self.particles} particles")
        for name, option, low, high, unit in (
                ("mixing_rate", "--mixing-rate", 0.0, 1.0, ""),
                ("process_noise_radius_rad", "--process-noise", 0.0, 0.5, " rad"),
                ("tactile_error_rate", "--tactile-error-rate", 0.0, 1.0, "")):
            value = getattr(self, name)
            if value is not None and not low <= value <= high:
                raise ValueError(f"{name} ({option}) must be in [{low:g}, {high:g}]{unit}, "
                                 f"got {value}")
        check_ranges(self, positive=("seconds_per_step", "estimator_period_s",
                                     "ball_radius_rad"),
                     at_most={"ball_radius_rad": np.pi, "seconds_per_step": 10.0,
                              "estimator_period_s": 10.0})
        check_proprioception(self.proprioception)
        check_dual_density(self.dual_density, self.metric, self.dual_share)
        check_dual_lift(self.dual_lift)


def commanded_trajectory(spec: ArmSpec, seconds_per_step: float) -> PiecewisePolynomial:
    """The arm file's trajectory as joint positions over time, linear between waypoints."""
    q = [np.array(spec.start_rad)]
    times = [0.0]
    for segment in spec.trajectory:
        q.append(np.array(segment.to_rad))
        times.append(times[-1] + segment.steps * seconds_per_step)
    return PiecewisePolynomial.FirstOrderHold(times, np.array(q).T)


def run_configest_episode(settings: ConfigestEpisodeSettings, out: Path, *,
                          meshcat: Meshcat | None = None, progress: bool = True) -> dict:
    """Simulate the episode; write its outputs into ``out``; return the summary."""
    from diagrams.herb.configest_report import plot_joint_error

    spec = ArmSpec.load(settings.arm)
    world = ArmWorld(spec, process_noise_radius_rad=settings.process_noise_radius_rad)
    scene = SceneSpec.load(spec.scene)
    layout = TactileLayout.load(settings.layout)
    period = settings.estimator_period_s
    offset = np.random.default_rng([settings.seed, OFFSET_STREAM]).normal(
        0.0, spec.offset_sd_rad, spec.dof)

    builder = DiagramBuilder()
    plant, scene_graph, herb = add_herb_plant(builder, scene, layout=layout, sim=settings.sim)
    trajectory = commanded_trajectory(spec, settings.seconds_per_step)
    arm_command = builder.AddSystem(TrajectorySource(trajectory, output_derivative_order=1))
    builder.Connect(arm_command.get_output_port(), plant.get_desired_state_input_port(herb.wam))
    commanded = builder.AddSystem(TrajectorySource(trajectory))
    fingers = tuple(s.name for s in spec.sensors)
    if not set(fingers) <= set(layout.fingers):
        raise ValueError(f"{spec.source}: the episode's sensors are the tactile system's "
                         f"fingers ({', '.join(layout.fingers)}), got {', '.join(fingers)}")
    error = (spec.sensor_error_rate if settings.tactile_error_rate is None
             else settings.tactile_error_rate)
    noise = TactileNoise(false_negative_rate=error, false_positive_rate_in_contact=error)
    tactile = builder.AddSystem(TactileSensor(
        layout, herb.hand.patch_geometry, noise=noise, seed=settings.seed,
        period_s=period, groups=SensorGroups(fingers, tuple((f,) for f in fingers))))
    builder.Connect(plant.get_contact_results_output_port(), tactile.get_input_port())
    indices = np.array([plant.GetJointByName(f"wam_j{k + 1}", herb.wam).position_start()
                        for k in range(spec.dof)])
    nx = plant.num_multibody_states()
    encoders = builder.AddSystem(Encoders(nx, indices, offset, spec.proprio_noise_radius_rad,
                                          seed=settings.seed, period_s=period))
    builder.Connect(plant.get_state_output_port(), encoders.get_input_port())
    selection = np.zeros((spec.dof, nx))
    selection[np.arange(spec.dof), indices] = 1.0
    truth = builder.AddSystem(MatrixGain(selection))
    builder.Connect(plant.get_state_output_port(), truth.get_input_port())

    estimators = {}
    for e, kind in enumerate(ESTIMATORS):
        if kind == "cpf":
            filt = make_filter("cpf", world,
                               outlier_log_evidence=settings.outlier_log_evidence)
            n = settings.particles
        else:
            filt = make_filter("mpf", world, ProjectionManifold(
                world, strategy="ball", ball_radius_rad=dual_ball_radius(
                    world, settings.dual_density, settings.ball_radius_rad),
                constraints=settings.constraints, metric=settings.metric),
                               dual_particles=settings.dual_particles,
                               mixing_rate=settings.mixing_rate,
                               dual_share=settings.dual_share,
                               outlier_log_evidence=settings.outlier_log_evidence,
                               dual_lift=make_dual_lift(world, settings.dual_lift))
            n = settings.particles - settings.dual_particles
        system = builder.AddSystem(ConfigurationEstimator(
            world, filt, particles=n, seed=settings.seed * 100 + e + 1, period_s=period,
            encoder_steps=settings.proprioception == "steps",
            history=kind == "mpf-ball" and settings.dual_density == "history"))
        system.set_name(f"estimator_{kind}")
        builder.Connect(encoders.get_output_port(), system.GetInputPort("encoders"))
        builder.Connect(commanded.get_output_port(), system.GetInputPort("commanded"))
        builder.Connect(tactile.GetOutputPort("sensor_contact"), system.GetInputPort("contact"))
        estimators[kind] = system
    logs = {kind: LogVectorOutput(system.GetOutputPort("mean"), builder, period)
            for kind, system in estimators.items()}
    logs["truth"] = LogVectorOutput(truth.get_output_port(), builder, period)
    logs["contact"] = LogVectorOutput(tactile.GetOutputPort("sensor_contact"), builder, period)
    logs["encoders"] = LogVectorOutput(encoders.get_output_port(), builder, period)
    logs["commanded"] = LogVectorOutput(commanded.get_output_port(), builder, period)
    visualizer = None
    if meshcat is not None:
        visualizer = add_meshcat(builder, plant, scene_graph, meshcat)
        drawer = builder.AddSystem(ArmBeliefDrawer(meshcat, world, means=len(estimators),
                                                   period_s=period))
        builder.Connect(estimators["mpf-ball"].GetOutputPort("belief"),
                        drawer.GetInputPort("belief"))
        for i, system in enumerate(estimators.values()):
            builder.Connect(system.GetOutputPort("mean"), drawer.GetInputPort(f"mean_{i}"))
        builder.Connect(truth.get_output_port(), drawer.GetInputPort("truth"))
        builder.Connect(tactile.GetOutputPort("sensor_contact"), drawer.GetInputPort("contact"))
    diagram = builder.Build()

    context = diagram.CreateDefaultContext()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(context),
                       herb.robot_positions(plant, np.array(spec.start_rad)))
    simulator = Simulator(diagram, context)
    if meshcat is not None:
        meshcat.SetCameraPose(camera_in_world=[0.2, -1.6, 1.6], target_in_world=[0.7, -0.3, 0.8])
        visualizer.StartRecording(False)
    simulator.Initialize()
    duration = trajectory.end_time()
    wall = time.perf_counter()
    for t in tqdm(np.arange(0.5, duration + 0.25, 0.5), desc="simulating", unit="0.5 s",
                  disable=not progress, leave=False):
        simulator.AdvanceTo(min(t, duration))
    wall = time.perf_counter() - wall
    out.mkdir(parents=True, exist_ok=True)
    if meshcat is not None:
        visualizer.StopRecording()
        visualizer.PublishRecording()
        (out / "replay.html").write_text(meshcat.StaticHtml())

    root = simulator.get_context()
    data = {k: log.FindLog(root) for k, log in logs.items()}
    times = data["truth"].sample_times()
    q_true = data["truth"].data().T
    errors = {kind: np.linalg.norm(wrap_angle(data[kind].data().T - q_true), axis=1)
              for kind in estimators}
    contact = data["contact"].data().T > 0.5
    tracking = np.linalg.norm(data["commanded"].data().T - q_true, axis=1)
    first = np.flatnonzero(contact.any(axis=1))
    summary = {
        "settings": {**asdict(settings), "sim": asdict(settings.sim)},
        "offset_rad": offset.tolist(),
        "duration_s": float(duration), "wall_s": wall,
        "contact_readings": int(contact.any(axis=1).sum()),
        "first_contact_s": float(times[first[0]]) if len(first) else None,
        "estimators": {kind: {
            "joint_error_rad_final": float(err[-1]),
            "joint_error_rad_mean": float(err.mean()),
            "joint_error_rad_mean_after_contact": (float(err[first[0]:].mean())
                                                   if len(first) else None),
            "contact_updates": estimators[kind].GetMyContextFromRoot(root)
            .get_abstract_state(0).get_value().contact_updates,
        } for kind, err in errors.items()},
        "encoder_error_rad_final": float(np.linalg.norm(wrap_angle(
            data["encoders"].data().T[-1] - q_true[-1]))),
        "tracking_error_rad": {  # how far the PD-controlled arm is from its command
            "max": float(tracking.max()), "mean": float(tracking.mean()),
            "mean_in_contact": (float(tracking[contact.any(axis=1)].mean())
                                if contact.any() else None)},
        "figures": [plot_joint_error(times, errors, contact, out / "joint_error.png")],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    np.savez_compressed(out / "episode.npz", times_s=times, q_true_rad=q_true,
                        contact=contact, encoders_rad=data["encoders"].data().T,
                        commanded_rad=data["commanded"].data().T,
                        **{f"mean_{kind}_rad": data[kind].data().T for kind in estimators})
    return summary
