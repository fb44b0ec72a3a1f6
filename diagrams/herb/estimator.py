"""The hand-relative estimator of the closed loop: a LeafSystem over
:class:`estimation.hand.tracker.HandRelativeTracker`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from estimation.hand.tracker import HandRelativeTracker, ParticleFilter
from estimation.particles.belief import ParticleBelief
from estimation.particles.filters import binary_reading


@dataclass(frozen=True)
class EstimatorState:
    """The estimator's Context state: the tracker, once the first check has read the palm
    pose it starts from (``None`` before)."""

    tracker: HandRelativeTracker | None = None

    def __deepcopy__(self, memo) -> EstimatorState:
        return self  # immutable: a copy would be the same value


class HandEstimator(LeafSystem):
    """The object's pose relative to the hand, as a particle belief.

    The belief lives in the Context, as an immutable :class:`EstimatorState`; the filter
    (CPF or MPF, with its contact manifold: costly to build, immutable) is a member shared
    by every Context. It checks every ``check_period_s`` and updates once the palm has
    travelled ``travel_m`` since its last update (or on every check when ``travel_m`` is
    None).

    Input ports: ``sensor_contact`` (S) binary readings, ``palm_pose`` (3) measured.
    Output ports: ``belief`` (abstract :class:`ParticleBelief`, hand frame), ``mean`` (3,
    hand frame), ``contact_seen`` (1).

    Args:
        filter: the CPF or the MPF (:func:`estimation.particles.factory.make_filter`).
        initial: the initial belief (hand frame).
        sensor_count: S.
        seed: update ``k`` draws from ``default_rng([seed, k])``.
        travel_m: palm travel between updates (m); ``None``: update on every check.
        check_period_s: how often to check (s).
    """

    def __init__(self, filter: ParticleFilter, initial: ParticleBelief, sensor_count: int, *,
                 seed: int = 0, travel_m: float | None = 0.005,
                 check_period_s: float = 0.01):
        super().__init__()
        self._filter = filter
        self._initial = initial
        self._seed = seed
        self._travel = travel_m
        self._readings = self.DeclareVectorInputPort("sensor_contact", sensor_count)
        self._palm = self.DeclareVectorInputPort("palm_pose", 3)
        self._state = self.DeclareAbstractState(AbstractValue.Make(EstimatorState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(check_period_s, 0.0, self._update)
        self.DeclareAbstractOutputPort("belief", lambda: AbstractValue.Make(initial),
                                       self._output_belief,
                                       prerequisites_of_calc={self.all_state_ticket()})
        self.DeclareVectorOutputPort("mean", 3, self._output_mean,
                                     prerequisites_of_calc={self.all_state_ticket()})
        self.DeclareVectorOutputPort("contact_seen", 1, self._output_contact,
                                     prerequisites_of_calc={self.all_state_ticket()})

    def tracker(self, context) -> HandRelativeTracker | None:
        """The tracker in ``context`` (``None`` before the first check)."""
        return context.get_abstract_state(int(self._state)).get_value().tracker

    def _update(self, context, state) -> EventStatus:
        palm = self._palm.Eval(context)
        tracker = self.tracker(context)
        if tracker is None:
            if not np.isfinite(palm).all():  # start at the first finite palm pose
                return EventStatus.DidNothing()
            tracker = HandRelativeTracker(self._initial, palm)
        else:
            moved = float(np.linalg.norm(palm[:2] - tracker.hand_pose_W[:2]))
            if self._travel is not None and moved < self._travel:
                return EventStatus.DidNothing()
            reading = binary_reading(self._readings.Eval(context))
            tracker = tracker.update(self._filter, palm, reading,
                                     rng=np.random.default_rng([self._seed, tracker.updates]))
        state.get_mutable_abstract_state(int(self._state)).set_value(EstimatorState(tracker))
        return EventStatus.Succeeded()

    def _belief(self, context) -> ParticleBelief:
        tracker = self.tracker(context)
        return self._initial if tracker is None else tracker.belief

    def _output_belief(self, context, output) -> None:
        output.set_value(self._belief(context))

    def _output_mean(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._belief(context).mean())

    def _output_contact(self, context, output: BasicVector) -> None:
        tracker = self.tracker(context)
        output.SetFromVector([float(tracker is not None and tracker.contact_seen)])
