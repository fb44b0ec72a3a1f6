"""The particle belief: an immutable weighted particle set over planar poses."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimation.particles.logmath import log_sum_exp
from models.pose import wrap_angle

ANGLE_INDEX = 2
"""States are (x m, y m, theta rad); column 2 is an angle."""


@dataclass(frozen=True)
class ParticleBelief:
    """A weighted particle set.

    Attributes:
        states: (N, 3) particles (x m, y m, theta rad).
        log_weights: (N,) unnormalised log weights.
    """

    states: np.ndarray
    log_weights: np.ndarray

    def __post_init__(self):
        if self.states.ndim != 2 or self.log_weights.shape != (len(self.states),):
            raise ValueError(f"states (N, d) and log_weights (N,) expected, got "
                             f"{self.states.shape} and {self.log_weights.shape}")
        self.states.setflags(write=False)
        self.log_weights.setflags(write=False)

    @staticmethod
    def uniform(states: np.ndarray) -> ParticleBelief:
        """Equally weighted particles."""
        return ParticleBelief(np.array(states, dtype=float), np.zeros(len(states)))

    def __len__(self) -> int:
        return len(self.states)

    @property
    def weights(self) -> np.ndarray:
        """(N,) normalised weights (uniform if every log weight is -inf)."""
        total = log_sum_exp(self.log_weights)
        if not np.isfinite(total):
            return np.full(len(self), 1.0 / len(self))
        return np.exp(self.log_weights - total)

    def effective_sample_size(self) -> float:
        """1 / sum(w_i^2) of the normalised weights."""
        w = self.weights
        return float(1.0 / np.sum(w * w))

    def mean(self) -> np.ndarray:
        """(3,) weighted mean; the angle is the circular mean."""
        w = self.weights
        xy = w @ self.states[:, :ANGLE_INDEX]
        theta = np.arctan2(w @ np.sin(self.states[:, ANGLE_INDEX]),
                           w @ np.cos(self.states[:, ANGLE_INDEX]))
        return np.array([xy[0], xy[1], theta])

    def rmse(self, true_state: np.ndarray) -> tuple[float, float]:
        """Weighted RMSE against a true state (thesis sec. 4.3.1), position and angle apart.

        Returns:
            (position RMSE m, orientation RMSE rad): sqrt(sum w_i |s_i - s*|^2 / sum w_i),
            with angle differences wrapped to [-pi, pi).
        """
        w = self.weights
        d = self.states[:, :ANGLE_INDEX] - np.asarray(true_state)[:ANGLE_INDEX]
        a = wrap_angle(self.states[:, ANGLE_INDEX] - true_state[ANGLE_INDEX])
        return float(np.sqrt(w @ (d * d).sum(1))), float(np.sqrt(w @ (a * a)))

    def resample(self, n: int | None = None, *, rng: np.random.Generator) -> ParticleBelief:
        """Low-variance (systematic) resampling to ``n`` equally weighted particles."""
        n = len(self) if n is None else n
        index = low_variance_indices(self.weights, n, rng=rng)
        return ParticleBelief.uniform(self.states[index])


def low_variance_indices(weights: np.ndarray, n: int, *, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``n`` draws by low-variance resampling (Thrun et al. 2005, Table 4.4).

    Args:
        weights: (N,) normalised weights.
    """
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    return np.searchsorted(cumulative, positions, side="right").clip(0, len(weights) - 1)
