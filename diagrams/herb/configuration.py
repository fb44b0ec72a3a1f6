"""The systems of robot configuration estimation in the HERB diagram (thesis sec. 5.5):
encoders behind a cable drive, the estimator, and its drawing in Meshcat.

Each is a thin adapter: the filter, the arm's kinematics and the encoder model are the
pure cores of :mod:`estimation` and :mod:`models.arms`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from estimation.configuration.belief import configuration_belief
from estimation.configuration.history import ReadingHistory
from estimation.configuration.proprioception import weigh_encoder_step
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import binary_reading
from models.arms.world import ArmWorld, ball_points

ENCODER_STREAM = 2
"""The encoders' noise is drawn from ``(seed, step, 2)``: a stream of its own, apart from the
tactile system's ``(seed, step)`` and ``(seed, step, 1)`` under the same seed."""


class Encoders(LeafSystem):
    """Joint encoders before a cable transmission: ``o_q = q + dq + eps`` (thesis
    sec. 3.2), a constant offset ``dq`` and noise uniform in a ball of ``noise_radius_rad``,
    sampled every ``period_s``.

    Input ports:
        state: the plant's state; the estimated joints are read at ``q_indices``.
    Output ports:
        encoders: (dof,) readings (rad).
    """

    def __init__(self, nx: int, q_indices: np.ndarray, offset: np.ndarray,
                 noise_radius_rad: float, *, seed: int, period_s: float):
        super().__init__()
        self._indices = np.asarray(q_indices)
        self._offset = np.asarray(offset, dtype=float)
        self._radius = noise_radius_rad
        self._seed = seed
        self._period = period_s
        dof = len(self._indices)
        self._state_port = self.DeclareVectorInputPort("state", nx)
        state = self.DeclareDiscreteState(dof)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, 0.0, self._sample)
        self.DeclareInitializationDiscreteUpdateEvent(self._sample)
        self.DeclareStateOutputPort("encoders", state)

    def _sample(self, context, discrete_state) -> EventStatus:
        q = self._state_port.Eval(context)[self._indices]
        step = int(round(context.get_time() / self._period))
        u = np.random.default_rng([self._seed, step, ENCODER_STREAM]).random((1, len(q) + 1))
        discrete_state.set_value(q + self._offset + ball_points(u, self._radius)[0])
        return EventStatus.Succeeded()


@dataclass(frozen=True)
class EstimatorState:
    """What the estimator keeps between updates (an immutable value in the Context).

    Attributes:
        belief: the particles, or None before the first update.
        commanded: (dof,) the last finite commanded configuration (rad).
        encoders: (dof,) the last encoder reading (rad; NaN before the first).
        contact_updates: updates so far with a contact reading.
        rejected_updates: updates whose encoders (before the first), commanded
            configuration or readings held a NaN or infinity.
        history: the readings so far, for the MPF's ``history`` dual density (None
            without it).
    """

    belief: ParticleBelief | None
    commanded: np.ndarray
    encoders: np.ndarray
    contact_updates: int = 0
    rejected_updates: int = 0
    history: ReadingHistory | None = None


class ConfigurationEstimator(LeafSystem):
    """Tracks the arm's configuration with a particle filter (CPF or MPF).

    The first update draws the initial belief from the encoders (``o_q - dq - eps``); each
    later one applies the commanded motion since the last update and the contact readings
    (:mod:`models.arms.world`). A non-finite input is counted and left out: non-finite
    encoders put off the start, a non-finite command holds the belief until a finite one
    (whose motion is then taken from the last finite command, so none is lost), and
    non-finite readings reach the filter as such, which propagates without weighting.

    Input ports:
        encoders: (dof,) proprioception (rad).
        commanded: (dof,) the commanded configuration (rad).
        contact: (S,) sensor readings (> 0.5 is contact), in the arm file's sensor order.
    Output ports:
        belief: the :class:`ParticleBelief` (abstract; before the first update, a
            one-particle placeholder at the zero configuration).
        mean: (dof,) the weighted mean of its configurations (rad; the encoders' reading
            before the first update).

    Args:
        world: the arm and its environment.
        filt: a filter with ``update(belief, action, observation, *, rng)``.
        particles: how many particles the belief holds.
        seed: seeds the initial belief and each update (``(seed, step)``).
        period_s: update period (s).
        encoder_steps: also weigh each update's encoder step (the ``steps``
            proprioception of :mod:`estimation.configuration.proprioception`).
        history: keep the readings and give the filter (an MPF) their exact predicted
            density for its duals (:mod:`estimation.configuration.history`).
    """

    def __init__(self, world: ArmWorld, filt, *, particles: int, seed: int,
                 period_s: float, encoder_steps: bool = False, history: bool = False):
        super().__init__()
        self._world, self._filter = world, filt
        self._particles, self._seed, self._period = particles, seed, period_s
        self._encoder_steps, self._history = encoder_steps, history
        dof = world.dof
        self._encoders = self.DeclareVectorInputPort("encoders", dof)
        self._commanded = self.DeclareVectorInputPort("commanded", dof)
        self._contact = self.DeclareVectorInputPort("contact", world.sensor_count)
        self._state = self.DeclareAbstractState(AbstractValue.Make(
            EstimatorState(None, np.zeros(dof), np.full(dof, np.nan))))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            "belief", lambda: AbstractValue.Make(ParticleBelief.uniform(np.zeros((1, dof)),
                                                                       world.angular)),
            self._output_belief, prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        self.DeclareVectorOutputPort("mean", dof, self._output_mean,
                                     prerequisites_of_calc={
                                         self.abstract_state_ticket(self._state),
                                         self._encoders.ticket()})

    def _update(self, context, state) -> EventStatus:
        current: EstimatorState = context.get_abstract_state(0).get_value()
        commanded = np.array(self._commanded.Eval(context))
        step = int(round(context.get_time() / self._period))
        rng = np.random.default_rng([self._seed, step])
        encoders = np.array(self._encoders.Eval(context))
        usable = np.isfinite(commanded).all() and (current.belief is not None
                                                   or np.isfinite(encoders).all())
        if not usable:
            new = replace(current, rejected_updates=current.rejected_updates + 1)
        elif current.belief is None:
            states = self._world.initial_belief_states(encoders, self._particles, rng=rng)
            history = (ReadingHistory.begin(encoders, commanded, self._world.sensor_count)
                       if self._history else None)
            new = EstimatorState(ParticleBelief.uniform(states, self._world.angular),
                                 commanded, encoders, 0, current.rejected_updates, history)
        else:
            readings = binary_reading(self._contact.Eval(context))
            finite = readings.dtype == bool  # NaN readings: the filter leaves them out
            action = commanded - current.commanded
            history = current.history
            if history is None:
                belief, _ = self._filter.update(current.belief, action, readings, rng=rng)
            else:
                belief, diagnostics = self._filter.update(
                    current.belief, action, readings, rng=rng,
                    dual_log_density=partial(history.log_density, self._world,
                                             commanded=commanded))
                if not diagnostics.rejected:  # neither non-finite nor gated as an outlier
                    history = history.appended(commanded, readings)
            if self._encoder_steps:  # a non-finite reading or last reading: not weighed
                belief = weigh_encoder_step(self._world, belief, action,
                                            self._world.angle_difference(
                                                encoders, current.encoders))
            new = EstimatorState(belief, commanded,
                                 encoders if np.isfinite(encoders).all() else current.encoders,
                                 current.contact_updates + int(finite and readings.any()),
                                 current.rejected_updates + int(not finite), history)
        state.get_mutable_abstract_state(0).set_value(new)
        return EventStatus.Succeeded()

    def _output_belief(self, context, output) -> None:
        current: EstimatorState = context.get_abstract_state(0).get_value()
        if current.belief is not None:
            output.set_value(current.belief)

    def _output_mean(self, context, output: BasicVector) -> None:
        current: EstimatorState = context.get_abstract_state(0).get_value()
        output.SetFromVector(self._encoders.Eval(context) if current.belief is None
                             else configuration_belief(self._world, current.belief).mean())


GHOST_RGBA = Rgba(0.2, 0.45, 0.95, 0.18)
MEAN_RGBAS = (Rgba(0.55, 0.55, 0.55, 1.0), Rgba(0.1, 0.35, 0.95, 1.0))
SENSOR_ON_RGBA = Rgba(1.0, 0.85, 0.0, 1.0)


class ArmBeliefDrawer(LeafSystem):
    """Draws beliefs over the arm's configuration as ghost arms: for a subset of one
    belief's particles, faint polylines through each link's joint origins and balls; each
    estimator's mean as a bold one (grey, blue, ...); the true arm's lit sensors as yellow
    balls. Each link's polyline is fixed in the link's frame and moved by transforms, so
    the recording (``StaticHtml``) replays the ghosts collapsing onto the arm on touch.

    Input ports:
        belief: the belief whose particles are drawn (abstract).
        mean_<i>: (dof,) each estimator's mean (rad).
        truth: (dof,) the true configuration (rad), for the lit sensors.
        contact: (S,) readings.
    """

    def __init__(self, meshcat: Meshcat, world: ArmWorld, *, means: int, particles: int = 20,
                 period_s: float = 0.1):
        super().__init__()
        self._meshcat, self._world, self._count = meshcat, world, particles
        dof = world.dof
        self._belief = self.DeclareAbstractInputPort("belief", AbstractValue.Make(
            ParticleBelief.uniform(np.zeros((1, dof)), world.angular)))
        self._means = [self.DeclareVectorInputPort(f"mean_{i}", dof) for i in range(means)]
        self._truth = self.DeclareVectorInputPort("truth", dof)
        self._contact = self.DeclareVectorInputPort("contact", world.sensor_count)
        self._ghosts = [f"/arm_belief/ghosts/{i}" for i in range(particles)]
        self._mean_paths = [f"/arm_belief/means/{i}" for i in range(means)]
        for k, line in enumerate(link_polylines(world)):
            for path in self._ghosts:
                meshcat.SetLine(f"{path}/{k}", line.T, 1.0, GHOST_RGBA)
            for i, path in enumerate(self._mean_paths):
                meshcat.SetLine(f"{path}/{k}", line.T, 4.0, MEAN_RGBAS[i % len(MEAN_RGBAS)])
        for s, balls in enumerate(world.sensors):
            for b, ball in enumerate(balls):
                meshcat.SetObject(f"/arm_belief/sensors/{s}/{b}", Sphere(ball.radius_m),
                                  SENSOR_ON_RGBA)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._draw)

    def _place(self, paths: list[str], q: np.ndarray, t: float) -> None:
        R, p, _, _ = self._world.chain.frames(q)
        for i, path in enumerate(paths):
            for k in range(self._world.dof):
                self._meshcat.SetTransform(
                    f"{path}/{k}", RigidTransform(RotationMatrix(R[i, k]), p[i, k]), t)

    def _draw(self, context) -> EventStatus:
        t, meshcat = context.get_time(), self._meshcat
        belief: ParticleBelief = self._belief.Eval(context)
        states = np.asarray(configuration_belief(self._world, belief).states)
        if len(states) > 1:
            self._place(self._ghosts,
                        states[np.linspace(0, len(states) - 1, self._count).astype(int)], t)
        self._place(self._mean_paths, np.array([port.Eval(context) for port in self._means]),
                    t)
        centres, _ = self._world.chain.centers(np.array(self._truth.Eval(context))[None])
        lit = self._contact.Eval(context) > 0.5
        index = 0
        for s, balls in enumerate(self._world.sensors):
            for b in range(len(balls)):
                path = f"/arm_belief/sensors/{s}/{b}"
                meshcat.SetTransform(path, RigidTransform(centres[0, index]), t)
                meshcat.SetProperty(path, "visible", bool(lit[s]), t)
                index += 1
        return EventStatus.Succeeded()


def link_polylines(world: ArmWorld) -> list[np.ndarray]:
    """Per chain link, (P, 3) points in its body frame: its joint's origin, the next
    joint's origin (for all but the last link), then the balls it carries."""
    chain = world.chain
    lines = []
    for k in range(chain.dof):
        points = [np.linalg.inv(chain.X_MC[k])[:3, 3]]
        if k + 1 < chain.dof:
            points.append(chain.X_PF[k + 1][:3, 3])
        points += list(chain.local[chain.link_index == k])
        if len(points) == 1:
            points.append(points[0])
        lines.append(np.array(points))
    return lines
