"""The Gaussian initial beliefs of the hand-relative experiments (thesis sec. 6.4.2, 6.4.3).

"Each belief point b_i was a Gaussian distribution with mean [x_i, y_i, theta_i] and
covariance Sigma^(1/2) = diag[5 cm, 5 cm, 15 deg]. The mean was a fixed distance x_i = 20 cm
in front of the hand with lateral offset y_i ~ uniform[-10 cm, 10 cm] and orientation
theta_i ~ uniform[0 deg, 360 deg]." The pre-contact experiments move the means to 50 cm.
We measure "in front of the hand" from the palm (the hand frame's origin; the fingertips
reach 11.7 cm), and condition every Gaussian on not overlapping the hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.planar.world import PlanarWorld

POST_CONTACT_DISTANCE_M = 0.20
PRE_CONTACT_DISTANCE_M = 0.50
BELIEF_STD = (0.05, 0.05, float(np.deg2rad(15.0)))


@dataclass(frozen=True)
class GaussianBelief:
    """N(mean, diag(std)^2) over object poses (x m, y m, theta rad) in the hand frame."""

    mean: tuple[float, float, float]
    std: tuple[float, float, float] = BELIEF_STD

    def sample(self, world: PlanarWorld, n: int, *, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) poses, conditioned on not overlapping the hand."""
        return world.sample_gaussian(np.array(self.mean), np.array(self.std), n, rng=rng)


def belief_points(count: int = 15, distance_m: float = POST_CONTACT_DISTANCE_M,
                  lateral_m: float = 0.10, *, rng: np.random.Generator
                  ) -> list[GaussianBelief]:
    """``count`` beliefs ``distance_m`` ahead with lateral offsets U[-lateral, lateral] and
    orientations U[-pi, pi) (thesis sec. 6.4.2)."""
    y = rng.uniform(-lateral_m, lateral_m, count)
    theta = rng.uniform(-np.pi, np.pi, count)
    return [GaussianBelief((distance_m, float(yi), float(ti))) for yi, ti in zip(y, theta,
                                                                                  strict=True)]
