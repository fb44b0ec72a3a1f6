"""Binary contact observations of the planar hand's sensors (thesis sec. 3.3 and 4.3.1).

An observation is a boolean vector, one entry per sensor: sensor i reads contact when the
object lies within ``tolerance_m`` of its segment. The noise model is the thesis': sensors
are "perfectly discriminative, but had a 10% chance of generating an incorrect observation
during contact". We read that per observation: while the object touches the hand, the
reported vector is the true one with probability ``1 - error_rate`` and otherwise one of
the other ``2^S - 1`` vectors, uniformly; while the object touches nothing the reading is
all-false (no false positives). A per-sensor flip model would make the thesis' sampling-
failure threshold (p(o|s) < 0.1, sec. 4.3.5) fail every sample once S > 21 sensors, which
the thesis' resolution experiment does not show.

The contact tolerance defaults to 1 mm, the physics step, "the same order of magnitude as
the numerical inaccuracies of the motion and observation models" (seed 000, sec. 6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.planar.polygon import ConvexPolygons, signed_distances

DEFAULT_CONTACT_TOLERANCE_M = 1e-3


@dataclass(frozen=True)
class ContactObservationModel:
    """Sensors, hand and object, with the noise parameters.

    Attributes:
        hand_parts: the hand (for "is the object touching the hand at all").
        sensors: sensor segments as two-vertex polygons, grouped by ``sensor_of_segment``.
        sensor_of_segment: (S_seg,) sensor index of each segment, non-decreasing.
        sensor_count: number of sensors S (at most 62).
        shape: the object's outline.
        tolerance_m: contact distance threshold (m).
        error_rate: probability of a wrong observation while in contact.
        backend: distance queries compiled (``"numba"``) or array reference (``"numpy"``).
    """

    hand_parts: ConvexPolygons
    sensors: ConvexPolygons
    sensor_of_segment: np.ndarray
    sensor_count: int
    shape: ConvexPolygons
    tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M
    error_rate: float = 0.1
    backend: str = "numba"

    def __post_init__(self):
        if not 1 <= self.sensor_count <= 62:
            raise ValueError(f"sensor_count must be in [1, 62], got {self.sensor_count}")
        if not 0.0 <= self.error_rate < 1.0:
            raise ValueError(f"error_rate must be in [0, 1), got {self.error_rate}")

    def hand_distance(self, states: np.ndarray) -> np.ndarray:
        """(K,) signed distance (m) from the object at ``states`` (K, 3) to the hand."""
        return signed_distances(self.hand_parts, self.shape, states,
                                exact_within=self.tolerance_m, backend=self.backend).min(axis=1)

    def in_contact(self, states: np.ndarray) -> np.ndarray:
        """(K,) whether the object touches (or overlaps) the hand."""
        return self.readings(states)[0]

    def true_contacts(self, states: np.ndarray) -> np.ndarray:
        """(K, S) noise-free readings: which sensors the object touches."""
        return self.readings(states)[1]

    def readings(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both tests at once: (K,) touches the hand, (K, S) touches each sensor."""
        states = np.ascontiguousarray(np.atleast_2d(states), dtype=float)
        if self.backend == "numba":
            from models.planar import kernels

            return kernels.contact_readings(
                states, *self.hand_parts.kernel_arrays, *self.sensors.kernel_arrays,
                self._owner, self.sensor_count, *self.shape.object_arrays, self.tolerance_m)
        d = signed_distances(self.sensors, self.shape, states, exact_within=self.tolerance_m,
                             backend="numpy")
        starts = np.r_[0, np.flatnonzero(np.diff(self.sensor_of_segment)) + 1]
        touching = np.minimum.reduceat(d, starts, axis=1) <= self.tolerance_m
        return self.hand_distance(states) <= self.tolerance_m, touching

    @property
    def _owner(self) -> np.ndarray:
        return np.ascontiguousarray(self.sensor_of_segment, dtype=np.int64)

    def log_likelihood(self, observation: np.ndarray, states: np.ndarray,
                       action: np.ndarray | None = None) -> np.ndarray:
        """log p(observation | state) for each of the (K, 3) states -> (K,).

        ``action`` is accepted for the interface of DESIGN.md; the reading depends on the
        state after the action only.
        """
        obs = self._check(observation)
        contact, touching = self.readings(states)
        match = (touching == obs[None]).all(axis=1)
        wrong = self.error_rate / (2.0 ** self.sensor_count - 1.0)
        with np.errstate(divide="ignore"):
            in_contact = np.where(match, np.log1p(-self.error_rate), np.log(wrong))
            free = np.where(obs.any(), -np.inf, 0.0)
        return np.where(contact, in_contact, free)

    def sample_observation(self, states: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Draw readings for (K, 3) states from uniforms ``u`` (K, 2) -> (K, S) bool."""
        contact, touching = self.readings(states)
        wrong = contact & (u[:, 0] < self.error_rate)
        # XOR with a uniformly drawn non-zero mask gives a uniformly drawn other vector.
        count = 2 ** self.sensor_count - 1
        mask = np.minimum((u[:, 1] * count).astype(np.int64), count - 1) + 1
        bits = (mask[:, None] >> np.arange(self.sensor_count)) & 1
        return np.where(wrong[:, None], touching ^ bits.astype(bool), touching)

    def _check(self, observation: np.ndarray) -> np.ndarray:
        obs = np.asarray(observation, dtype=bool)
        if obs.shape != (self.sensor_count,):
            raise ValueError(f"observation must have shape ({self.sensor_count},), got "
                             f"{obs.shape}")
        return obs


def observation_key(observation: np.ndarray) -> int:
    """An integer that identifies a (S,) boolean observation (bit i = sensor i)."""
    return int((np.asarray(observation, dtype=np.int64) << np.arange(len(observation))).sum())


def observation_reading(key: int, sensor_count: int) -> np.ndarray:
    """(S,) boolean observation of the key :func:`observation_key` gives it."""
    return (int(key) >> np.arange(sensor_count)) & 1 == 1


def observation_keys(observations: np.ndarray) -> np.ndarray:
    """(K,) integer keys of (K, S) boolean observations."""
    obs = np.asarray(observations, dtype=np.int64)
    return (obs << np.arange(obs.shape[1])).sum(axis=1)
