"""The planar world bundle: hand, object, pushing (transition) and contact (observation)
models, with the batched interface of DESIGN.md.

>>> world = PlanarWorld.load("box", sensors="medium")
>>> world.step(states, np.array([0.005, 0, 0]), u)       # (K, 3) -> (K, 3)
>>> world.log_likelihood(observation, states)             # (K,)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.objects import ObjectSpec
from models.planar.hand import PlanarHand, PlanarSensorLayout
from models.planar.observation import DEFAULT_CONTACT_TOLERANCE_M, ContactObservationModel
from models.planar.polygon import ConvexPolygons
from models.planar.pushing import PushingModel, PushingParameters


@dataclass(frozen=True)
class PlanarWorld:
    """Everything the hand-relative estimators and planners need.

    Attributes:
        hand: the planar hand with its sensors.
        object_spec: the pushed object.
        shape: its outline as a polygon (about its centroid, the centre of friction).
        pushing: the transition model.
        sensing: the observation model.
    """

    hand: PlanarHand
    object_spec: ObjectSpec
    shape: ConvexPolygons
    pushing: PushingModel
    sensing: ContactObservationModel

    @staticmethod
    def load(object_name_or_path: str | Path = "box",
             sensors: str | Path | PlanarSensorLayout = "medium", *,
             pushing: PushingParameters = PushingParameters(),
             tolerance_m: float = DEFAULT_CONTACT_TOLERANCE_M,
             error_rate: float = 0.1, backend: str = "numba") -> PlanarWorld:
        """Build from an object (built-in name or YAML path) and a sensor layout.

        ``backend`` selects the compiled kernels (``"numba"``) or the numpy reference.
        """
        hand = PlanarHand.load(sensors)
        spec = ObjectSpec.load(object_name_or_path)
        shape = ConvexPolygons.from_list([spec.footprint()])
        model = PushingModel(hand.parts, shape, pushing, backend)
        sensing = ContactObservationModel(hand.parts, hand.sensor_polygons,
                                          hand.sensor_of_segment, hand.sensor_count, shape,
                                          tolerance_m, error_rate, backend)
        return PlanarWorld(hand, spec, shape, model, sensing)

    @property
    def sensor_count(self) -> int:
        return self.hand.sensor_count

    def uniforms_per_step(self, action: np.ndarray) -> int:
        return self.pushing.uniforms_per_step(action)

    def step(self, states: np.ndarray, action: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Transition (K, 3) states under ``action`` given uniforms (K, D); see pushing."""
        return self.pushing.step(states, action, u)

    def sample_step(self, states: np.ndarray, action: np.ndarray, *,
                    rng: np.random.Generator) -> np.ndarray:
        """Transition with freshly drawn uniforms."""
        u = rng.random((len(states), self.uniforms_per_step(action)))
        return self.pushing.step(states, action, u)

    def log_likelihood(self, observation: np.ndarray, states: np.ndarray,
                       action: np.ndarray | None = None) -> np.ndarray:
        return self.sensing.log_likelihood(observation, states, action)

    def sample_observation(self, states: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self.sensing.sample_observation(states, u)

    def in_contact(self, states: np.ndarray) -> np.ndarray:
        return self.sensing.in_contact(states)

    def overlap_free(self, states: np.ndarray) -> np.ndarray:
        """(K,) whether the object at each state does not overlap the hand (1 um slack)."""
        return self.sensing.hand_distance(states) > -1e-6

    def sample_gaussian(self, mean: np.ndarray, std: np.ndarray, n: int, *,
                        rng: np.random.Generator, max_rounds: int = 100) -> np.ndarray:
        """Draw ``n`` states from N(mean, diag(std)^2) conditioned on not overlapping the hand.

        Args:
            mean: (3,) mean pose (m, m, rad); std: (3,) standard deviations.

        Raises:
            ValueError: when almost all of the distribution overlaps the hand.
        """
        mean, std = np.asarray(mean, dtype=float), np.asarray(std, dtype=float)
        out = np.empty((0, 3))
        for _ in range(max_rounds):
            draw = mean + std * rng.standard_normal((max(2 * n, 16), 3))
            draw[:, 2] = (draw[:, 2] + np.pi) % (2 * np.pi) - np.pi
            out = np.vstack([out, draw[self.overlap_free(draw)]])
            if len(out) >= n:
                return out[:n]
        raise ValueError(f"the belief N({mean}, {std}) lies almost entirely inside the hand")
