"""The particle belief: an immutable weighted particle set over states of any dimension.

A planar object pose ``(x m, y m, theta rad)`` is the default state, with column 2 an angle;
a 7-joint configuration or a lattice state declares its own angular columns, which the
weighted mean averages on the circle and the RMSE compares wrapped to [-pi, pi).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimation.particles.logmath import log_sum_exp
from models.pose import wrap_angle

PLANAR_ANGULAR = (2,)
"""The angular columns of a planar pose (x m, y m, theta rad): column 2."""


@dataclass(frozen=True)
class ParticleBelief:
    """A weighted particle set; immutable (its arrays are read-only), so systems may hold it
    as a state value and share it without copying.

    Attributes:
        states: (N, d) particles (default: planar poses x m, y m, theta rad).
        log_weights: (N,) unnormalised log weights.
        angular: the columns of ``states`` that are angles (rad), averaged on the circle
            and compared wrapped; the other columns are linear (e.g. metres).
    """

    states: np.ndarray
    log_weights: np.ndarray
    angular: tuple[int, ...] = PLANAR_ANGULAR

    def __post_init__(self):
        if self.states.ndim != 2 or self.log_weights.shape != (len(self.states),):
            raise ValueError(f"states (N, d) and log_weights (N,) expected, got "
                             f"{self.states.shape} and {self.log_weights.shape}")
        d = self.states.shape[1]
        if len(set(self.angular)) != len(self.angular) or \
                any(not 0 <= c < d for c in self.angular):
            raise ValueError(f"angular columns {self.angular} must be distinct columns of "
                             f"a {d}-dimensional state")
        self.states.setflags(write=False)
        self.log_weights.setflags(write=False)

    def __deepcopy__(self, memo) -> ParticleBelief:
        return self  # immutable: a copy would be the same value

    @staticmethod
    def uniform(states: np.ndarray, angular: tuple[int, ...] = PLANAR_ANGULAR
                ) -> ParticleBelief:
        """Equally weighted particles."""
        return ParticleBelief(np.array(states, dtype=float), np.zeros(len(states)),
                              tuple(angular))

    @property
    def linear(self) -> tuple[int, ...]:
        """The columns that are not angles."""
        return tuple(c for c in range(self.states.shape[1]) if c not in self.angular)

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
        """(d,) weighted mean; angular columns are circular means."""
        w = self.weights
        out = np.empty(self.states.shape[1])
        out[list(self.linear)] = w @ self.states[:, list(self.linear)]
        for c in self.angular:
            out[c] = np.arctan2(w @ np.sin(self.states[:, c]), w @ np.cos(self.states[:, c]))
        return out

    def rmse(self, true_state: np.ndarray) -> tuple[float, float]:
        """Weighted RMSE against a true state (thesis sec. 4.3.1), linear and angular
        columns apart.

        Returns:
            (linear RMSE, angular RMSE rad): sqrt(sum w_i |s_i - s*|^2 / sum w_i) over the
            linear columns (m for a planar pose) and over the angular ones, with angle
            differences wrapped to [-pi, pi); 0.0 for a part with no columns.
        """
        w = self.weights
        true_state = np.asarray(true_state, dtype=float)
        lin, ang = list(self.linear), list(self.angular)
        d = self.states[:, lin] - true_state[lin]
        a = wrap_angle(self.states[:, ang] - true_state[ang])
        return float(np.sqrt(w @ (d * d).sum(1))), float(np.sqrt(w @ (a * a).sum(1)))

    def resample(self, n: int | None = None, *, rng: np.random.Generator) -> ParticleBelief:
        """Low-variance (systematic) resampling to ``n`` equally weighted particles."""
        n = len(self) if n is None else n
        index = low_variance_indices(self.weights, n, rng=rng)
        return ParticleBelief.uniform(self.states[index], self.angular)


def low_variance_indices(weights: np.ndarray, n: int, *, rng: np.random.Generator) -> np.ndarray:
    """Indices of ``n`` draws by low-variance resampling (Thrun et al. 2005, Table 4.4).

    Args:
        weights: (N,) normalised weights.
    """
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0
    return np.searchsorted(cumulative, positions, side="right").clip(0, len(weights) - 1)
