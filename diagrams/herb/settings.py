"""The settings of one closed-loop episode (thesis sec. 6.5)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from models.contact import SimulationConfig
from models.herb.tactile import TactileNoise
from models.settings import check_ranges
from planning.hand.precontact import PreContactSettings
from planning.lattice.planners import check_budget
from planning.lattice.pomdp import OUTSIDE_MODES

ESTIMATORS = ("mpf", "cpf")
PLANNER_BELIEFS = ("estimator", "thesis")
POLICIES = ("qmdp", "pomdp")
PLANNERS = ("hand", "lat-despot")
LAT_DESPOT_MODELS = ("discrete", "continuous")
#: The thesis' three initial beliefs (sec. 6.5): means 35 cm ahead at lateral offsets 12,
#: 0 and 6 cm; its figure shows the first to the hand's right (-y).
THESIS_BELIEF_MEANS = ((0.35, -0.12, 0.0), (0.35, 0.0, 0.0), (0.35, 0.06, 0.0))
TOPPLED_RAD = float(np.deg2rad(45.0))
"""An object tilted further than this has fallen over; the episode ends."""


# Ceilings on the episode's magnitudes (each in its field's unit): far beyond any sensible
# run (HERB reaches about 1 m; the WAM's palm moves well under 1 m/s) and low enough that a
# mistyped exponent is refused rather than simulated.
EPISODE_CEILINGS = {"belief_mean": 10.0, "belief_std": 10.0, "hand_speed_m_per_s": 2.0,
                    "travel_m": 0.5, "time_step_s": 0.1, "lat_despot_seconds": 3600.0}


@dataclass(frozen=True)
class EpisodeSettings:
    """One closed-loop episode.

    Attributes:
        scene: scene name or path (its object is replaced by ``object_name``).
        object_name: the pushed object; it must be the planning model's. The thesis'
            real-robot trials pushed a bottle (sec. 6.5), and so do these: the small box
            of the simulations (3.5 cm x 5 cm, 12 cm tall) topples in Drake when a finger
            pushes it above about 5 cm, which HERB's fingers do (F2 at about 8.5 cm).
        planner: ``hand``: the hand-relative planner of ch. 6 (pre-contact search, then
            ``policy``), blind to the arm; ``lat-despot``: Lat-DESPOT (thesis ch. 7) on the
            same hand-relative model over the scene's configuration lattice (the model's
            step apart), its scenarios drawn from the estimator's particles, the arm moved
            along the lattice edges it checked.
        policy: post-contact policy of the ``hand`` planner, ``qmdp`` or ``pomdp``.
        lat_despot_trials: DESPOT trials per Lat-DESPOT decision (None: the wall-clock
            cap alone); lat_despot_seconds: its wall-clock cap per decision (s). DESPOT's
            other settings are its defaults (K = 500 scenarios, depth 90, as the JAIR
            paper; the ch. 7 study uses K = 100).
        lat_despot_model: what Lat-DESPOT plans on: ``discrete`` (the thesis: the
            discretised hand-relative model, the particles mapped to its cells) or
            ``continuous`` (beyond the thesis: the planar pushing model itself, the
            particles as they are, with the same bounds; as part ``rel``'s
            ``rel-despot-continuous``).
        lat_despot_outside: with the ``continuous`` model, how Lat-DESPOT's bounds value
            an object outside the planning model's region: ``sentinel`` (the discrete
            model's absorbing -1 a step) or ``return`` (the steps back to the region, then
            the bounds there); :mod:`planning.lattice.pomdp`.
        estimator: ``mpf`` (manifold particle filter, analytic manifold) or ``cpf``.
        estimator_outlier_log_evidence: the estimator's outlier gate (beyond the thesis;
            :class:`~estimation.particles.filters.ConventionalParticleFilter`): a reading
            whose evidence log p(o | b+) is below it, and which no dual explains, is
            propagated through without weighing; None (default): every reading weighed,
            as the thesis. The fault bench uses -30.
        planner_belief: what the policy acts on: ``estimator`` (the estimator system's
            belief, discretised after contact; :class:`~planning.hand.planner.HandPlanner`)
            or ``thesis`` (the policy's own particle filter, then the planning model's
            discrete Bayes filter, sec. 6.4.1;
            :class:`~planning.hand.planner.ThesisHandPlanner`).
        belief_mean: (x m, y m, theta rad) of the initial belief, hand frame.
        belief_std: its standard deviations (thesis sec. 6.5: 5 cm; 15 deg as sec. 6.4.2).
        particles: estimator particles.
        horizon: decisions per episode.
        on_infeasible: ``stop``: the episode ends when the policy's action is infeasible
            (the thesis' real-robot rule, sec. 6.5); ``next``: fall back to the next-ranked
            feasible action (at the arm's reach this drags a captured object sideways, so
            it is not the default).
        precontact: the pre-contact search's settings.
        hand_speed_m_per_s: nominal palm speed.
        travel_m: palm travel between estimator updates (m).
        posture_weight: the IK's pull towards HERB's home posture
            (:class:`~models.herb.kinematics.PlanarHandIK`); without it (0) warm-started
            motions drift into postures that collide in the middle of the workspace (4 of
            40 forward-biased random walks, against none with 0.05).
        layout: Drake tactile layout (``distal_links``: every face of each distal link).
        noise: the tactile sensors' noise (thesis: 10 % wrong readings during contact).
        time_step_s: the plant's time step.
        seed: seeds the true pose, the particles, the sensors' noise, the filter and the
            planner.
    """

    scene: str = "closed_loop"
    object_name: str = "bottle"
    planner: str = "hand"
    policy: str = "pomdp"
    lat_despot_trials: int | None = 100
    lat_despot_seconds: float = 2.0
    lat_despot_model: str = "discrete"
    lat_despot_outside: str = "sentinel"
    estimator: str = "mpf"
    estimator_outlier_log_evidence: float | None = None
    planner_belief: str = "estimator"
    belief_mean: tuple[float, float, float] = THESIS_BELIEF_MEANS[1]
    belief_std: tuple[float, float, float] = (0.05, 0.05, float(np.deg2rad(15.0)))
    particles: int = 500
    horizon: int = 30
    on_infeasible: str = "stop"
    precontact: PreContactSettings = field(default_factory=PreContactSettings)
    hand_speed_m_per_s: float = 0.05
    travel_m: float = 0.005
    posture_weight: float = 0.05
    layout: str = "distal_links"
    noise: TactileNoise = field(default_factory=TactileNoise)
    time_step_s: float = SimulationConfig().time_step_s
    seed: int = 0

    def __post_init__(self):
        if self.planner not in PLANNERS:
            raise ValueError(f"planner must be one of {PLANNERS}, got {self.planner!r}")
        check_budget(self.lat_despot_trials, self.lat_despot_seconds)
        if self.lat_despot_model not in LAT_DESPOT_MODELS:
            raise ValueError(f"lat_despot_model must be one of {LAT_DESPOT_MODELS}, got "
                             f"{self.lat_despot_model!r}")
        if self.lat_despot_outside not in OUTSIDE_MODES:
            raise ValueError(f"lat_despot_outside must be one of {OUTSIDE_MODES}, got "
                             f"{self.lat_despot_outside!r}")
        if self.lat_despot_outside != "sentinel" and self.lat_despot_model != "continuous":
            raise ValueError("lat_despot_outside 'return' needs lat_despot_model "
                             "'continuous'")
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if self.estimator not in ESTIMATORS:
            raise ValueError(f"estimator must be one of {ESTIMATORS}, got {self.estimator!r}")
        if self.estimator_outlier_log_evidence is not None and \
                not self.estimator_outlier_log_evidence < 0:
            raise ValueError(f"estimator_outlier_log_evidence must be < 0 or null, got "
                             f"{self.estimator_outlier_log_evidence}")
        if self.planner_belief not in PLANNER_BELIEFS:
            raise ValueError(f"planner_belief must be one of {PLANNER_BELIEFS}, got "
                             f"{self.planner_belief!r}")
        check_ranges(self, positive=("belief_std", "hand_speed_m_per_s", "travel_m",
                                     "time_step_s"), non_negative=("posture_weight",),
                     at_most=EPISODE_CEILINGS)
        if self.particles < 10 or self.horizon < 1:
            raise ValueError("particles must be >= 10 and horizon >= 1")
        if self.on_infeasible not in ("next", "stop"):
            raise ValueError(f"on_infeasible must be 'next' or 'stop', got "
                             f"{self.on_infeasible!r}")
