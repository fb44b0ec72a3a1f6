"""Factor-graph smoothing of a pushed object's pose from vision and touch (seed 003, sec.
IV), on GTSAM's iSAM2.

One ``Pose2`` per estimator step (100 Hz). Each step adds (sec. IV-A, Fig. 3):

- the stationary prior between the previous pose and this one (always);
- the pushing motion cost between them, from the forces at the previous step (when a rod
  touched then);
- one contact cost per rod in contact now;
- beyond the paper, one penetration cost per rod whose position is known but whose force
  reading was lost (:func:`estimation.pushing.costs.penetration_residual`): while the
  force sensors are blind the rods still push the object out of their way;
- the vision cost, Huber-robust, when a camera pose arrived.

The motion and contact costs are :mod:`estimation.pushing.costs` wrapped as
``gtsam.CustomFactor`` with their analytic Jacobians. The stationary and vision costs are
GTSAM's own ``BetweenFactorPose2`` and ``PriorFactorPose2``, whose residual is the
difference in the first pose's frame (``Logmap(a^-1 b)``) rather than eq. 4's world frame;
with the covariance turned into that frame when the factor is made (by the previous pose's
estimated heading, or the camera's measured one), the two costs agree to first order.
Measured: on the simulated rig, whose identified covariances are nearly isotropic in x, y,
estimates differ by at most 0.6 mm and 1.2 deg and the RMSE by under 1 %; with a strongly
anisotropic stationary covariance and an object that turns after its factors were made
(the tests' straight-push log) they differ by up to 4 mm, the RMSE by 1 %. The C++
factors linearise about 10x faster than Python callbacks, which halves a 300-pose batch
relinearisation (36 to 18 ms) and keeps it within its budget. ``native_factors=False``
uses eq. 4 verbatim. GTSAM is the maintained iSAM2 implementation (Kaess et al.); we use it
rather than writing a sparse incremental QR of our own.

History (sec. V-G): ``history`` poses are kept. ``relinearize_every`` steps after the last
rebuild, or as soon as the window holds ``history + chunk`` poses (``chunk =
min(relinearize_every, history)``), the window is rebuilt in batch: the oldest poses beyond
``history`` are dropped, a prior replaces them on
the oldest kept pose, and the whole window is relinearised at the current estimate by a
fresh iSAM2. With history 200 and every 100 steps this is the paper's scheme exactly (keep
200; at 300 drop the oldest 100; relinearise in batch every 100). Between rebuilds:

- ``relinearization="batch"`` (the paper's iSAM1): old poses are not relinearised;
- ``relinearization="fluid"``: iSAM2's own relinearisation of poses that moved (beyond the
  paper).

The prior on the oldest kept pose is ``"weak"`` in the paper; ``"marginal"`` (default) is
what the dropped steps knew about it: their factors linearised at the current estimate
with the dropped poses eliminated (:meth:`VisuoTactileSmoother._marginal_prior`), the
standard fixed-lag marginalisation.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from estimation.pushing.costs import (
    Outline,
    contact_points,
    contact_residual,
    motion_residual,
    penetration_residual,
    stationary_residual,
    vision_residual,
)
from estimation.pushing.inputs import PushingSteps
from estimation.pushing.noise import COSTS, PushingNoise

MIN_CONTACT_FORCE_N = 1e-9
"""A rod reading contact with less force than this (N) is left out (see ``_usable``)."""

#: iSAM2's relinearisation threshold in "fluid" mode (m, m, rad of a pose's update).
FLUID_THRESHOLD = 1e-3


@dataclass(frozen=True)
class SmootherSettings:
    """Attributes:
        history: poses kept (>= 1).
        relinearize_every: steps between batch rebuilds (>= 1).
        relinearization: ``"batch"`` (paper) or ``"fluid"`` (iSAM2's own).
        drop_prior: ``"marginal"`` or ``"weak"`` (paper), on the oldest kept pose.
        weak_prior_sigma: (3,) m, m, rad: the weak prior's standard deviations.
        costs: which of motion, contact, vision, stationary to use.
        stationary: ``"pooled"`` (seed 003: one covariance for every step) or
            ``"contact-aware"`` (the covariance of pushed steps when a rod touches at either
            end of the step, of free steps otherwise; needs a noise model that has them).
        extra_iterations: further iSAM2 updates without new factors after each step (each
            one more Gauss-Newton step; with ``"fluid"`` relinearisation it relinearises
            the newest pose at its new estimate). 0 in the paper.
        native_factors: the stationary and vision costs as GTSAM's C++ ``BetweenFactorPose2``
            and ``PriorFactorPose2`` (default), or as Python ``CustomFactor`` s of eq. 4's
            world-frame residuals (the faithful form; about 10x slower to linearise).
        c_m: the limit surface's c (m); ``None``: the noise model's (its ``c_scale`` times
            the outline's uniform-pressure value).
    """

    history: int = 200
    relinearize_every: int = 100
    relinearization: str = "batch"
    drop_prior: str = "marginal"
    weak_prior_sigma: tuple[float, float, float] = (0.05, 0.05, 0.5)
    costs: tuple[str, ...] = COSTS
    stationary: str = "pooled"
    extra_iterations: int = 0
    native_factors: bool = True
    c_m: float | None = None

    def __post_init__(self) -> None:
        if self.history < 1 or self.relinearize_every < 1 or self.extra_iterations < 0:
            raise ValueError("history and relinearize_every must be >= 1, extra_iterations "
                             ">= 0")
        if self.relinearization not in ("batch", "fluid"):
            raise ValueError(f"relinearization={self.relinearization!r}: batch or fluid")
        if self.drop_prior not in ("marginal", "weak"):
            raise ValueError(f"drop_prior={self.drop_prior!r}: marginal or weak")
        if self.stationary not in ("pooled", "contact-aware"):
            raise ValueError(f"stationary={self.stationary!r}: pooled or contact-aware")
        unknown = set(self.costs) - set(COSTS)
        if unknown:
            raise ValueError(f"unknown costs {sorted(unknown)}; allowed: {', '.join(COSTS)}")


def recommended_settings(history: int = 200) -> SmootherSettings:
    """Beyond the paper: its scheme with the contact-aware stationary prior.
    ``cmanip experiment visuotactile --part methods`` measures it against the paper's
    scheme (which :class:`SmootherSettings` defaults to) and against iSAM2's fluid
    relinearisation, which helps the pooled prior (rotation 3.98 -> 3.42 deg) but not this
    one (1.91 -> 2.17 deg)."""
    return SmootherSettings(history=history, stationary="contact-aware")


def _pose(values: gtsam.Values, key: int) -> np.ndarray:
    p = values.atPose2(key)
    return np.array([p.x(), p.y(), p.theta()])


class VisuoTactileSmoother:
    """The estimator; feed it one step at a time with :meth:`step`.

    Args:
        polygon: (V, 2) the object's outline (m, convex, counter-clockwise).
        noise: the costs' covariances.
        settings: history, relinearisation, costs.
        rod_radius_m: the rods' radius (m).

    Attributes:
        update_seconds, rebuild_seconds: wall time of each update and window rebuild (s).
        rejected_inputs: rod readings and camera poses left out because they were not
            finite (:meth:`step` goes on without them).
    """

    def __init__(self, polygon: np.ndarray, noise: PushingNoise,
                 settings: SmootherSettings = SmootherSettings(), *, rod_radius_m: float):
        self.polygon = np.asarray(polygon, dtype=float)
        self.outline = Outline(self.polygon)
        self.settings = settings
        self.radius = rod_radius_m
        self.c = settings.c_m if settings.c_m is not None else noise.limit_surface_c(self.polygon)
        aware = settings.stationary == "contact-aware"
        if aware and noise.stationary_pushed is None:
            raise ValueError("a contact-aware stationary prior needs a noise model with "
                             "stationary_pushed and stationary_free")
        self._huber = gtsam.noiseModel.mEstimator.Huber.Create(noise.vision_huber_k)
        self._models = {
            "motion": gtsam.noiseModel.Gaussian.Covariance(noise.motion),
            "contact": gtsam.noiseModel.Gaussian.Covariance(noise.contact),
            # the contact cost's signed-distance row
            "penetration": gtsam.noiseModel.Isotropic.Sigma(1, float(np.sqrt(
                noise.contact[0, 0]))),
            "vision": gtsam.noiseModel.Robust.Create(
                self._huber, gtsam.noiseModel.Gaussian.Covariance(noise.vision)),
        }
        self._stationary_covariances = {pushed: noise.stationary_covariance(pushed, aware)
                                        for pushed in (False, True)}
        self._stationary_models = {pushed: gtsam.noiseModel.Gaussian.Covariance(covariance)
                                   for pushed, covariance
                                   in self._stationary_covariances.items()}
        self._vision_cov = noise.vision
        self._steps: deque[tuple[int, list, list]] = deque()  # (k, own factors, linking)
        self._k = -1
        self._first = 0
        self._previous_inputs = None
        self._estimate = None
        self._isam = None
        self.update_seconds: list[float] = []
        self.rebuild_seconds: list[float] = []
        self.rejected_inputs = 0

    @property
    def started(self) -> bool:
        return self._isam is not None

    def _params(self) -> gtsam.ISAM2Params:
        params = gtsam.ISAM2Params()
        if self.settings.relinearization == "batch":
            params.enableRelinearization = False
        else:  # relinearise any pose whose update exceeds 1 mm or 1 mrad, at every update
            params.setRelinearizeThreshold(FLUID_THRESHOLD)
            params.relinearizeSkip = 1
        return params

    def start(self, pose: np.ndarray, covariance: np.ndarray | None = None) -> None:
        """Begin at ``pose`` (3,) with a prior of ``covariance`` (default: the vision
        cost's)."""
        self._k = 0
        self._first = 0
        self._isam = gtsam.ISAM2(self._params())
        prior = gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*pose), gtsam.noiseModel.Gaussian
                                       .Covariance(self._vision_cov if covariance is None
                                                   else covariance))
        self._prior = [prior]
        graph = gtsam.NonlinearFactorGraph()
        graph.add(prior)
        values = gtsam.Values()
        values.insert(X(0), gtsam.Pose2(*pose))
        self._isam.update(graph, values)
        self._steps.append((0, [], []))
        self._since_rebuild = 0
        self._estimate = np.asarray(pose, dtype=float)

    def step(self, rods: np.ndarray, forces: np.ndarray, contact: np.ndarray,
             vision: np.ndarray | None) -> np.ndarray:
        """Add one step's measurements and return the current pose estimate (3,).

        Args:
            rods: (2, 2) rod centres (m). forces: (2, 2) forces on the object (N).
            contact: (2,) bool. vision: (3,) a new camera pose, or ``None``.
        """
        if not self.started:
            raise RuntimeError("call start() first")
        rods, forces, contact, vision, blind = self._usable(rods, forces, contact, vision)
        unknown = blind is not None
        begin = time.perf_counter()
        costs = self.settings.costs
        self._k += 1
        k = self._k
        own, linking = [], []
        previous = self._previous_inputs
        if "stationary" in costs:
            pushed = bool(np.any(contact)) or unknown or (previous is not None
                                                          and previous[2].any())
            linking.append(self._stationary(k, pushed))
        if "motion" in costs and previous is not None and previous[2].any():
            touching = previous[2]
            points = contact_points(previous[0][touching], previous[1][touching], self.radius)
            linking.append(self._motion(k, previous[1][touching], points))
        if "contact" in costs:
            for rod in np.flatnonzero(contact):
                own.append(self._contact(k, rods[rod], forces[rod]))
            for rod in () if blind is None else blind:
                own.append(self._penetration(k, rod))
        if "vision" in costs and vision is not None:
            own.append(self._vision(k, vision))
        self._previous_inputs = (np.array(rods), np.array(forces), np.array(contact, bool))
        graph = gtsam.NonlinearFactorGraph()
        for factor in own + linking:
            graph.add(factor)
        values = gtsam.Values()
        values.insert(X(k), gtsam.Pose2(*self._estimate))
        self._steps.append((k, own, linking))
        self._since_rebuild += 1
        chunk = min(self.settings.relinearize_every, self.settings.history)
        if (self._since_rebuild >= self.settings.relinearize_every
                or len(self._steps) >= self.settings.history + chunk):
            self._since_rebuild = 0
            self._isam.update(graph, values)
            rebuild = time.perf_counter()
            self._rebuild()
            self.rebuild_seconds.append(time.perf_counter() - rebuild)
        else:
            self._isam.update(graph, values)
            for _ in range(self.settings.extra_iterations):
                self._isam.update()
        estimate = self._isam.calculateEstimatePose2(X(k))
        self._estimate = np.array([estimate.x(), estimate.y(), estimate.theta()])
        self.update_seconds.append(time.perf_counter() - begin)
        return self._estimate

    def _usable(self, rods, forces, contact, vision):
        """The step's inputs with every unusable one left out, each counted in
        :attr:`rejected_inputs`: a rod whose centre or force holds a NaN or infinity, or
        that reads contact with no force (the contact cost needs the force's direction),
        has its contact and motion costs dropped, and the step's stationary prior is the
        pushed one (the rod may be pushing: taking it as free would hold the object still
        against the camera); where its centre is finite it keeps a penetration cost. A
        camera pose with a NaN or infinity is taken as no camera frame. A factor with a
        NaN measurement would make the whole window's solution NaN.

        Returns:
            rods, forces, contact, vision as :meth:`step` takes them, and the (B, 2)
            centres of the rods left out whose centre is finite (None when none was left
            out).
        """
        rods = np.asarray(rods, dtype=float)
        forces = np.asarray(forces, dtype=float)
        contact = np.array(contact, dtype=bool)
        finite = np.isfinite(rods).all(axis=1) & np.isfinite(forces).all(axis=1)
        # a NaN force compares False, so only the finite ones can read as forceless
        bad = ~finite | (contact & (np.abs(forces).sum(axis=1) < MIN_CONTACT_FORCE_N))
        blind = None
        if bad.any():
            blind = rods[bad & np.isfinite(rods).all(axis=1)]
            self.rejected_inputs += int(bad.sum())
            contact &= ~bad
            rods = np.where(bad[:, None], 0.0, rods)
            forces = np.where(bad[:, None], 0.0, forces)
        if vision is not None and not np.all(np.isfinite(vision)):
            self.rejected_inputs += 1
            vision = None
        return rods, forces, contact, vision, blind

    def run(self, steps: PushingSteps, *, start: np.ndarray | None = None) -> np.ndarray:
        """Estimate every step of ``steps``; (K, 3), nan before the first camera pose (or
        from step 0 at ``start``)."""
        def begin(first, pose):
            self.start(pose)
            self._previous_inputs = steps.inputs(first)
            return self._estimate

        return steps.estimate(begin, lambda k: self.step(*steps.inputs(k), steps.vision_at(k)),
                              start)

    # -- window
    def _rebuild(self) -> None:
        """Drop the oldest poses if the window is full, then relinearise it in batch."""
        s = self.settings
        chunk = min(s.relinearize_every, s.history)
        estimate = self._isam.calculateEstimate()
        first = self._first
        if len(self._steps) >= s.history + chunk:
            first = self._k - s.history + 1
        if first != self._first:
            if s.drop_prior == "marginal":
                self._prior = self._marginal_prior(first, estimate)
            else:
                model = gtsam.noiseModel.Diagonal.Sigmas(np.array(s.weak_prior_sigma))
                self._prior = [gtsam.PriorFactorPose2(X(first), estimate.atPose2(X(first)),
                                                      model)]
            while self._steps[0][0] < first:
                self._steps.popleft()
            self._first = first
        graph = gtsam.NonlinearFactorGraph()
        for factor in self._prior:
            graph.add(factor)
        values = gtsam.Values()
        for k, own, linking in self._steps:
            values.insert(X(k), estimate.atPose2(X(k)))
            for factor in own + (linking if k > first else []):
                graph.add(factor)
        # eliminate the newest pose last, so that the next steps, which touch it, only
        # re-eliminate the top of the Bayes tree (as in a chronologically grown chain)
        newest = gtsam.KeyGroupMap()
        newest.insert2(X(self._k), 1)
        self._isam = gtsam.ISAM2(self._params())
        self._isam.update(graph, values, constrainedKeys=newest)

    def _marginal_prior(self, first: int, estimate: gtsam.Values) -> list:
        """What the dropped steps knew about pose ``first``: the factors of the dropped
        poses (with the previous prior, and the factors that link them to ``first``),
        linearised at the current estimate, with the dropped poses eliminated (a Schur
        complement), kept as linear factors on ``first``. The factors on ``first`` itself
        stay in the window, so nothing is counted twice."""
        dropped = gtsam.NonlinearFactorGraph()
        for factor in self._prior:
            dropped.add(factor)
        keys = []
        for k, own, linking in self._steps:
            if k > first:
                break
            if k < first:
                keys.append(X(k))
                for factor in own:
                    dropped.add(factor)
            if k > self._first:
                for factor in linking:
                    dropped.add(factor)
        values = gtsam.Values()
        for key in keys + [X(first)]:
            values.insert(key, estimate.atPose2(key))
        ordering = gtsam.Ordering()
        for key in keys:
            ordering.push_back(key)
        _, remaining = dropped.linearize(values).eliminatePartialMultifrontal(ordering)
        at_first = gtsam.Values()
        at_first.insert(X(first), estimate.atPose2(X(first)))
        return [gtsam.LinearContainerFactor(remaining.at(i), at_first)
                for i in range(remaining.size()) if remaining.at(i) is not None]

    # -- factors
    def _stationary(self, k: int, pushed: bool):
        if self.settings.native_factors:
            covariance = _rotated(self._stationary_covariances[pushed], self._estimate[2])
            return gtsam.BetweenFactorPose2(X(k - 1), X(k), gtsam.Pose2(),
                                            gtsam.noiseModel.Gaussian.Covariance(covariance))

        def error(this, values, H):
            a, b = _pose(values, this.keys()[0]), _pose(values, this.keys()[1])
            r, J1, J2 = stationary_residual(a, b)
            if H is not None:
                H[0], H[1] = J1, J2
            return r
        return gtsam.CustomFactor(self._stationary_models[pushed], [X(k - 1), X(k)], error)

    def _motion(self, k: int, forces: np.ndarray, points: np.ndarray) -> gtsam.CustomFactor:
        c = self.c

        def error(this, values, H):
            a, b = _pose(values, this.keys()[0]), _pose(values, this.keys()[1])
            r, J1, J2 = motion_residual(a, b, forces, points, c)
            if H is not None:
                H[0], H[1] = J1, J2
            return r
        return gtsam.CustomFactor(self._models["motion"], [X(k - 1), X(k)], error)

    def _contact(self, k: int, rod: np.ndarray, force: np.ndarray) -> gtsam.CustomFactor:
        polygon, radius = self.outline, self.radius
        rod, force = np.array(rod), np.array(force)

        def error(this, values, H):
            r, J = contact_residual(_pose(values, this.keys()[0]), rod, force, radius, polygon)
            if H is not None:
                H[0] = J
            return r
        return gtsam.CustomFactor(self._models["contact"], [X(k)], error)

    def _penetration(self, k: int, rod: np.ndarray) -> gtsam.CustomFactor:
        polygon, radius = self.outline, self.radius
        rod = np.array(rod)

        def error(this, values, H):
            r, J = penetration_residual(_pose(values, this.keys()[0]), rod, radius, polygon)
            if H is not None:
                H[0] = J
            return r
        return gtsam.CustomFactor(self._models["penetration"], [X(k)], error)

    def _vision(self, k: int, measured: np.ndarray):
        measured = np.array(measured)
        if self.settings.native_factors:
            model = gtsam.noiseModel.Robust.Create(self._huber, gtsam.noiseModel.Gaussian
                                                   .Covariance(_rotated(self._vision_cov,
                                                                        measured[2])))
            return gtsam.PriorFactorPose2(X(k), gtsam.Pose2(*measured), model)

        def error(this, values, H):
            r, J = vision_residual(_pose(values, this.keys()[0]), measured)
            if H is not None:
                H[0] = J
            return r
        return gtsam.CustomFactor(self._models["vision"], [X(k)], error)


def _rotated(covariance: np.ndarray, theta: float) -> np.ndarray:
    """A world-frame pose covariance (3, 3) expressed in a frame turned by ``theta``: the
    frame of GTSAM's Pose2 differences, ``Logmap(a^-1 b) ~ [R(theta_a)^T (p_b - p_a),
    theta_b - theta_a]``."""
    c, s = np.cos(theta), np.sin(theta)
    B = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return B @ covariance @ B.T
