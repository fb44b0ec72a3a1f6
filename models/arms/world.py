"""An arm in its known static world: contact sensing, the motion model and proprioception
(thesis sec. 3.2, 3.3 and 5.4.1), batched over K configurations.

**State.** A particle is the arm's *commanded-side* configuration q (dof,) rad: where the
arm would be without contact, the encoders' reading less the offset
(``q = o_q - dq - eps``). Its actual configuration is ``Pi(q)``, q projected out of
inter-penetration (below); out of contact the two are the same. The offset is constant
over an experiment (sec. 5.4.1: drawn once per trial), so this state is the offset in
disguise, the representation of the authors' 2-D demo (TouchFilter2D: configuration =
encoders + offset particle); we keep it in configuration space, where the contact
manifold, the projection and the error the thesis plots live. The encoders' first reading
gives the initial belief, ``o_q,0 - dq - eps`` with ``dq ~ N(0, Sigma_dq)`` and
``eps ~ U(B(0, r_q))``; later readings repeat the same offset plus fresh noise, so they
are not weighed again (that would count the offset once per step).

**Motion** (sec. 5.4.1): the commanded joint motion, then a frictionless projection out of
inter-penetration: Gauss-Newton on the penetration depths of the arm's balls (each ball
moves along its contact normal only), joint limits clipped, planar joints wrapped. HERB's
arm is position-controlled: it goes to each commanded configuration unless an obstacle is
in the way, and returns to the commanded path when the contact ends. So the commanded
motion moves the state, and the projection gives the actual configuration from it at
every step, without being accumulated (in the authors' demo, too, the pushed-out
configuration lasts one step). The filter adds ``process_noise_radius_rad`` of uniform
noise in a ball to each commanded step (the thesis' motion is deterministic; a particle
filter needs some diffusion, and the authors' demo uses a 0.01 rad random walk).

**Contact sensing** (sec. 3.3, eq. 5.3): sensor i is active when
``f_i(q) = min_j F(c_ij(q)) - r_ij <= contact_tolerance_m``; while the arm touches
any sensor touches, each reading is flipped with probability ``sensor_error_rate``, and
while none touches, a reading is on with probability ``free_false_positive_rate`` (the
thesis' model of sec. 4.4.1: "perfectly discriminative", wrong only during contact).
The likelihood also counts each ball deeper than ``PENETRATION_TOLERANCE_M`` (beyond the
arm's ``press_depth_m``) inside an obstacle as one contradicted reading: such a state
is (almost) impossible, and dual samples projected onto a contact can land there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

from models.arms.chain import BallChain
from models.arms.environment import Environment
from models.arms.plant import ArmModel, build_arm, geometry_balls
from models.arms.spec import ArmSpec
from models.pose import wrap_angle

FREE_READING_FLOOR = 1e-6
"""The likelihood's floor for a contact reading where the arm touches nothing."""

PENETRATION_TOLERANCE_M = 0.005
"""A ball deeper than this inside an obstacle makes a state (nearly) impossible (m)."""

FREE_ITERATIONS = 40
"""Gauss-Newton iterations of the projection out of penetration."""

MAX_FREE_STEP_RAD = 0.05
"""Trust region of one projection step (rad): a deep penetration is undone in small steps
that follow the contact normals, not by one linearised jump that can land anywhere."""

FREE_TOLERANCE_M = 1e-5
"""The projection out of penetration stops when no ball is deeper than this (m)."""

DAMPING = 1e-2
"""Levenberg damping (m^2) of the projection's joint-space normal equations."""


@dataclass(frozen=True)
class ArmTrajectory:
    """One simulated experiment.

    Attributes:
        q_true: (T+1, dof) true configurations (rad), from the start.
        q_free: (T+1, dof) the true state: the commanded-side configurations, which
            ``q_true`` is projected from (rad).
        commanded: (T, dof) commanded joint motion per step (rad).
        encoders: (T+1, dof) proprioceptive readings o_q = q + dq + eps (rad).
        contacts: (T+1, S) bool contact readings (after the start, and each step).
        offset: (dof,) the encoder offset dq (rad).
    """

    q_true: np.ndarray
    q_free: np.ndarray
    commanded: np.ndarray
    encoders: np.ndarray
    contacts: np.ndarray
    offset: np.ndarray


class ArmWorld:
    """The batched models the filters need (:class:`models.protocols.FilterModel`).

    Args:
        spec: the arm, its sensors, world and noise.
        process_noise_radius_rad: the filter's per-step motion noise (rad).

    Attributes:
        sensors: each sensor's balls, listed or covering its links' geometry.
        balls: every ball, the sensors' (in sensor order) then the body's.
        sensor_of_ball: (B,) the sensor each ball belongs to, -1 for the body.
    """

    def __init__(self, spec: ArmSpec, *, process_noise_radius_rad: float = 0.01):
        if process_noise_radius_rad < 0:
            raise ValueError("process_noise_radius_rad must be >= 0")
        self.spec = spec
        self.model: ArmModel = build_arm(spec)
        self.process_noise_radius_rad = process_noise_radius_rad
        diagram = self.model.diagram
        self.context = diagram.CreateDefaultContext()
        plant = diagram.plant()
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        plant.SetPositions(self.plant_context, self.model.q_default)
        query = diagram.scene_graph().get_query_output_port().Eval(
            diagram.scene_graph().GetMyContextFromRoot(self.context))
        self.environment = Environment.from_scene_graph(
            diagram.scene_graph().model_inspector(), query, self.model.environment_ids)
        self.sensors = tuple(s.balls + geometry_balls(self.model, s.links)
                             for s in spec.sensors)
        body = spec.body + geometry_balls(self.model, spec.body_links)
        self.balls = tuple(b for balls in self.sensors for b in balls) + body
        self.chain = BallChain(plant, self.plant_context, self.model.joints, self.balls)
        self.sensor_of_ball = np.concatenate(
            [np.full(len(balls), i) for i, balls in enumerate(self.sensors)]
            + [np.full(len(body), -1)]).astype(int)
        self.dof = spec.dof
        self.sensor_count = len(spec.sensors)
        # planar joints live on the circle; the WAM's are limited (an angle past +-pi is a
        # different configuration, not the same one wrapped)
        self.angular = tuple(range(self.dof)) if self.model.continuous else ()
        self.lower, self.upper = self.model.lower, self.model.upper
        self._last_projection: tuple | None = None

    # -- geometry ---------------------------------------------------------------------

    def ball_distances(self, q: np.ndarray, *, gradient: bool = False,
                       balls: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray | None]:
        """Signed distance of every ball to the environment, ``F(c_j(q)) - r_j``.

        Args:
            q: (K, dof) configurations (rad).
            balls: indices of the balls wanted (default: all B).

        Returns:
            (K, B) distances (m) and, when asked, their gradients (K, B, dof) m/rad
            (thesis eq. 5.4: ``grad F(c)^T J_c(q)``).
        """
        c, J = self.chain.centers(q, jacobian=gradient, balls=balls)
        d, g = self.environment.signed_distance(c)
        d = d - (self.chain.radii if balls is None else self.chain.radii[balls])[None]
        if not gradient:
            return d, None
        return d, np.einsum("kbi,kbid->kbd", g, J)

    def sensor_distances(self, q: np.ndarray, *, gradient: bool = False,
                         sensors: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray | None]:
        """f_i(q) of each sensor (thesis eq. 5.3: its nearest ball) and, when asked, the
        gradient (eq. 5.4: the nearest ball's).

        Args:
            q: (K, dof) configurations (rad).
            sensors: sorted indices of the sensors wanted (default: all S); only their
                balls are evaluated.

        Returns:
            (K, S') distances (m) and (K, S', dof) gradients (m/rad) or None.
        """
        q = np.atleast_2d(q)
        sensors = np.arange(self.sensor_count) if sensors is None else np.asarray(sensors)
        balls = np.flatnonzero(np.isin(self.sensor_of_ball, sensors))
        d, g = self.ball_distances(q, gradient=gradient, balls=balls)
        out, best = _group_minimum(d, np.searchsorted(sensors, self.sensor_of_ball[balls]),
                                   len(sensors))
        if not gradient:
            return out, None
        return out, np.take_along_axis(g, best[..., None], axis=1)

    def _sensor_minimum(self, d: np.ndarray) -> np.ndarray:
        """(K, S) each sensor's nearest ball, from all balls' distances (K, B)."""
        sensing = self.sensor_of_ball >= 0
        return _group_minimum(d[:, sensing], self.sensor_of_ball[sensing],
                              self.sensor_count)[0]

    def true_contacts(self, q: np.ndarray) -> np.ndarray:
        """(K, S) noise-free readings: f_i(q) <= contact tolerance."""
        return self.sensor_distances(q)[0] <= self.spec.contact_tolerance_m

    def in_contact(self, states: np.ndarray) -> np.ndarray:
        """(K,) would any sensor read contact at the states' actual configurations?"""
        return self.true_contacts(self.project_free(states)).any(axis=1)

    # -- motion -----------------------------------------------------------------------

    def normalise(self, q: np.ndarray) -> np.ndarray:
        """Planar angles wrapped to [-pi, pi); WAM joints clipped to their limits."""
        return wrap_angle(q) if self.model.continuous else np.clip(q, self.lower, self.upper)

    def angle_difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``a - b`` of configurations (rad): wrapped for planar joints."""
        difference = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
        return wrap_angle(difference) if self.model.continuous else difference

    def project_free(self, q: np.ndarray) -> np.ndarray:
        """The frictionless projection out of inter-penetration (thesis sec. 5.4.1).

        Gauss-Newton on ``1/2 sum_j min(0, d_j(q) + p)^2`` over the arm's balls, p the
        arm file's ``press_depth_m`` (0, the thesis' rigid model, unless the arm presses
        into compliant contact): each step
        solves ``(J^T J + lambda I) dq = -J^T r`` with the penetrating balls' rows, so the
        arm moves along the contact normals only (no friction).

        Args:
            q: (K, dof) configurations (rad), possibly penetrating.

        Returns:
            (K, dof) configurations with no ball deeper than the press depth plus
            ``FREE_TOLERANCE_M`` where the iterations reached it. The last answer is kept
            (read-only): a filter update asks for the same predicted particles' projection
            in its likelihood and its free-space test.
        """
        q = np.asarray(q, dtype=float)
        key = (q.shape, q.tobytes())
        if self._last_projection is not None and self._last_projection[0] == key:
            return self._last_projection[1]
        projected = self._project_free(q)
        projected.setflags(write=False)
        self._last_projection = (key, projected)
        return projected

    def _project_free(self, q: np.ndarray) -> np.ndarray:
        """:meth:`project_free` without the memo."""
        q = self.normalise(np.array(q, dtype=float))
        eye = np.eye(self.dof)[None]
        press = self.spec.press_depth_m
        d, _ = self.ball_distances(q)
        deep = np.flatnonzero(d.min(axis=1) + press < -FREE_TOLERANCE_M)
        for _ in range(FREE_ITERATIONS):
            if deep.size == 0:
                break
            d, g = self.ball_distances(q[deep], gradient=True)
            r = np.minimum(d + press, 0.0)
            still = r.min(axis=1) < -FREE_TOLERANCE_M
            deep, r, g = deep[still], r[still], g[still] * (r[still] < 0)[..., None]
            A = np.einsum("kbi,kbj->kij", g, g) + DAMPING * eye
            step = np.linalg.solve(A, -np.einsum("kbi,kb->ki", g, r)[..., None])[..., 0]
            norm = np.linalg.norm(step, axis=1, keepdims=True)
            step *= np.minimum(1.0, MAX_FREE_STEP_RAD / np.maximum(norm, 1e-12))
            q[deep] = self.normalise(q[deep] + step)
        return q

    def uniforms_per_step(self, action: np.ndarray) -> int:
        """dof normal directions plus one radius for the ball noise."""
        return self.dof + 1

    def step(self, states: np.ndarray, action: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(K, dof) states after the commanded motion ``action`` (dof,) rad, plus noise
        uniform in a ball of ``process_noise_radius_rad`` from ``u`` (K, dof + 1)."""
        noise = ball_points(u, self.process_noise_radius_rad)
        return self.normalise(np.asarray(states) + np.asarray(action)[None] + noise)

    def sample_step(self, states: np.ndarray, action: np.ndarray, *,
                    rng: np.random.Generator) -> np.ndarray:
        u = rng.random((len(states), self.uniforms_per_step(action)))
        return self.step(states, action, u)

    # -- observation ------------------------------------------------------------------

    def log_likelihood(self, observation: np.ndarray, states: np.ndarray,
                       action: np.ndarray | None = None) -> np.ndarray:
        """(K,) log p(o | q) at the states' actual configurations (thesis sec. 4.4.1's
        sensor model): while any sensor touches, each reading is right with probability
        1 - e and wrong with e; while none touches, each reads contact with probability
        f0 (``free_false_positive_rate``, floored at :data:`FREE_READING_FLOOR` so that no
        reading is impossible). A ball still deep inside an obstacle counts as one wrong
        reading more."""
        e, f0 = self.spec.sensor_error_rate, self.spec.free_false_positive_rate
        f0 = max(f0, FREE_READING_FLOOR)
        d, _ = self.ball_distances(self.project_free(np.atleast_2d(states)))
        sensed = self._sensor_minimum(d) <= self.spec.contact_tolerance_m
        observation = np.asarray(observation, bool)
        wrong = (sensed != observation[None]).sum(1)
        touching = sensed.any(axis=1)
        lit = int(observation.sum())
        log_p = np.where(touching, (self.sensor_count - wrong) * np.log1p(-e)
                         + wrong * np.log(e),
                         lit * np.log(f0) + (self.sensor_count - lit) * np.log1p(-f0))
        deep = d < -(PENETRATION_TOLERANCE_M + self.spec.press_depth_m)
        return log_p + deep.sum(axis=1) * np.log(e)

    def encoder_step_log_likelihood(self, states: np.ndarray, action: np.ndarray,
                                    encoder_step: np.ndarray) -> np.ndarray:
        """(K,) log p(o_q,t - o_q,t-1 | q_t): the encoders' step since the last reading
        against the states' (K, dof) predicted step of the actual configuration,
        ``Pi(q_t) - Pi(q_t - a_t)`` (the commanded motion ``action`` (dof,) rad, where a
        contact stops or deflects the arm). The constant offset cancels in the step; the
        noise ``eps_t - eps_t-1`` of two readings uniform in the r_q-ball is taken as
        Gaussian with its variance, ``2 r_q^2 / (dof + 2)`` per joint. Consecutive steps
        share a reading's noise, so a run of them counts it twice: a known approximation,
        preferred to carrying each particle's reading history."""
        states = np.atleast_2d(states)
        before = self.project_free(self.normalise(states - np.asarray(action)[None]))
        predicted = self.angle_difference(self.project_free(states), before)
        residual = self.angle_difference(np.asarray(encoder_step)[None], predicted)
        variance = 2.0 * self.spec.proprio_noise_radius_rad ** 2 / (self.dof + 2)
        return -0.5 * (residual ** 2).sum(axis=1) / max(variance, 1e-12)

    def sample_observation(self, states: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(K, S) readings at the states' actual configurations: each flipped when ``u``
        (K, S) < e while any sensor touches; each on when ``u`` < f0 while none does."""
        return self._readings(self.true_contacts(self.project_free(states)), u)

    def _readings(self, truth: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(K, S) readings from the noise-free contacts ``truth`` (K, S) and uniforms."""
        touching = truth.any(axis=1, keepdims=True)
        return np.where(touching, truth ^ (u < self.spec.sensor_error_rate),
                        u < self.spec.free_false_positive_rate)

    # -- experiments ------------------------------------------------------------------

    def initial_belief_states(self, encoders: np.ndarray, n: int, *,
                              rng: np.random.Generator) -> np.ndarray:
        """(n, dof) configurations ``o_q - dq - eps`` for the first reading (dof,) rad,
        with ``dq ~ N(0, sd^2 I)`` and ``eps ~ U(B(0, r_q))``."""
        dq = rng.normal(0.0, self.spec.offset_sd_rad, (n, self.dof))
        eps = ball_points(rng.random((n, self.dof + 1)), self.spec.proprio_noise_radius_rad)
        return self.normalise(np.asarray(encoders)[None] - dq - eps)

    def initial_log_density(self, encoders: np.ndarray, states: np.ndarray) -> np.ndarray:
        """(K,) log density, up to a constant, of :meth:`initial_belief_states` for the
        first reading ``encoders`` (dof,) at ``states`` (K, dof) rad: the Gaussian offset
        convolved with the uniform noise ball, taken as a Gaussian of the summed variance
        ``sd^2 + r_q^2 / (dof + 2)`` per joint (the ball's share is small where the offset
        dominates, as in every arm file here)."""
        variance = (self.spec.offset_sd_rad ** 2
                    + self.spec.proprio_noise_radius_rad ** 2 / (self.dof + 2))
        residual = self.angle_difference(np.asarray(encoders)[None], np.atleast_2d(states))
        return -0.5 * (residual ** 2).sum(axis=1) / max(variance, 1e-12)

    def simulate(self, *, rng: np.random.Generator) -> ArmTrajectory:
        """The true arm along the commanded trajectory, and what it senses: an offset
        ``dq ~ N(0, sd^2 I)`` for the whole run; each step the commanded configuration,
        projected out of penetration; encoders ``q + dq + eps``; contact readings with
        flips."""
        commanded = self.spec.commanded_steps()
        dq = rng.normal(0.0, self.spec.offset_sd_rad, self.dof)
        q_free = self.normalise(np.array(self.spec.start_rad)[None] + np.concatenate(
            [np.zeros((1, self.dof)), np.cumsum(commanded, axis=0)]))
        q_true = self.project_free(q_free)
        eps = ball_points(rng.random((len(q_true), self.dof + 1)),
                          self.spec.proprio_noise_radius_rad)
        contacts = self._readings(self.true_contacts(q_true),
                                  rng.random((len(q_true), self.sensor_count)))
        encoders = q_true + dq + eps  # not clipped: the offset carries past the limits
        return ArmTrajectory(q_true, q_free, commanded,
                             wrap_angle(encoders) if self.model.continuous else encoders,
                             contacts, dq)


def _group_minimum(d: np.ndarray, group: np.ndarray, groups: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``d`` (K, B), the minimum over the columns of each group (``group`` (B,)
    in [0, groups)) and the column that attains it: (K, groups), (K, groups). A loop over
    the few columns, vectorised over the K rows."""
    out = np.full((len(d), groups), np.inf)
    best = np.zeros((len(d), groups), dtype=int)
    for b, s in enumerate(group):
        closer = d[:, b] < out[:, s]
        out[:, s] = np.where(closer, d[:, b], out[:, s])
        best[:, s] = np.where(closer, b, best[:, s])
    return out, best


def ball_points(u: np.ndarray, radius: float) -> np.ndarray:
    """Points uniform in the d-ball of ``radius`` from uniforms ``u`` (K, d + 1): d normal
    deviates (inverse CDF) give the direction, ``u_d ** (1/d)`` the radius fraction."""
    d = u.shape[1] - 1
    z = ndtri(np.clip(u[:, :d], 1e-12, 1 - 1e-12))
    norm = np.linalg.norm(z, axis=1, keepdims=True)
    direction = z / np.where(norm > 0, norm, 1.0)
    return direction * (radius * u[:, d:] ** (1.0 / d))
