"""Tactile patches on the hand: their layout (data) and the pure sensing functions.

A *patch* is a named region of the hand's surface that reports contact: the fingertips,
the inner (closing) faces of the distal and proximal links, and strips of the palm. The
layout, which surfaces and how finely subdivided, is a data file
(``models/assets/tactile/*.yaml``), so the resolution experiments change data, not code.
Each patch is its own collision geometry on the hand (see :mod:`models.herb.hand`), so the
contact results of the plant attribute every contact force to the patches it touches.

The noise model follows the thesis (Koval 2016, sec. 4.4.1 and 6.4.1): sensors are
"perfectly discriminative, but had a 10% chance of generating an incorrect observation
during contact": no false positives while the hand touches nothing, and each patch reading
is wrong with probability 0.1 while the hand is in contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.config import Fields, resolve_asset
from models.settings import check_ranges

FINGERS = ("f1", "f2", "f3")


@dataclass(frozen=True)
class TactileLayout:
    """Which hand surfaces carry sensing patches, and how many.

    Attributes:
        fingers: fingers that carry patches (subset of f1, f2, f3).
        fingertips: a patch on the last ``tip_length`` of each distal link.
        distal_inner_segments: patches along the inner face of each distal link (0 = none).
        proximal_inner_segments: patches along the inner face of each proximal link.
        palm_strips: strips across the palm pad, ordered from -y (F1/F2 side) to +y (F3).
        distal_outer: a patch on the outer face of each distal link (``f1_distal_outer``),
            the face a pushed object meets; with the tip and inner patches it makes the
            whole distal link a sensor, like HERB's strain gauges (thesis sec. 6.5).
    """

    fingers: tuple[str, ...] = FINGERS
    fingertips: bool = True
    distal_inner_segments: int = 1
    proximal_inner_segments: int = 1
    palm_strips: int = 3
    distal_outer: bool = False

    @property
    def patch_names(self) -> tuple[str, ...]:
        """Names of all patches, in the order of every per-patch output vector."""
        names: list[str] = []
        for finger in self.fingers:
            if self.fingertips:
                names.append(f"{finger}_tip")
            names += [f"{finger}_distal_{i}" for i in range(self.distal_inner_segments)]
            if self.distal_outer:
                names.append(f"{finger}_distal_outer")
            names += [f"{finger}_proximal_{i}" for i in range(self.proximal_inner_segments)]
        names += [f"palm_{i}" for i in range(self.palm_strips)]
        return tuple(names)

    @staticmethod
    def load(name_or_path: str | Path = "default") -> TactileLayout:
        """Load a layout by built-in name (``default``, ``fingertips``, ``dense``,
        ``distal_links``) or path.

        A layout holds no physical quantity (the patches' sizes follow from the hand file):
        it says which surfaces are split into how many patches. Omitted fields take the
        ``default`` layout's values (all fingers, fingertips, one inner patch per link,
        three palm strips, no ``distal_outer`` patch); only ``distal_links`` turns
        ``distal_outer`` on, the other built-in layouts rely on it being off.

        Raises:
            ConfigError: naming the file and field of a malformed entry, or when the layout
                defines no patch.
        """
        fields = Fields.from_file(resolve_asset("tactile", name_or_path))
        layout = TactileLayout(
            fingers=fields.string_list("fingers", FINGERS, choices=FINGERS),
            fingertips=fields.boolean("fingertips", True),
            distal_inner_segments=int(
                fields.number("distal_inner_segments", 1, min=0, max=20, integer=True)
            ),
            proximal_inner_segments=int(
                fields.number("proximal_inner_segments", 1, min=0, max=20, integer=True)
            ),
            palm_strips=int(fields.number("palm_strips", 3, min=0, max=50, integer=True)),
            distal_outer=fields.boolean("distal_outer", False),
        )
        fields.done()
        if not layout.patch_names:
            raise fields.error("", "the layout defines no patch at all")
        return layout


def patch_force_magnitudes(
    pair_patch: np.ndarray, pair_force_W: np.ndarray, num_patches: int
) -> np.ndarray:
    """Sum contact forces per patch and return their magnitudes.

    Args:
        pair_patch: (K,) int, the patch index of each contact pair's hand-side geometry,
            or -1 when that geometry is not a patch (pair ignored).
        pair_force_W: (K, 3) contact force (N) on the hand geometry, world frame.
        num_patches: P.

    Returns:
        (P,) magnitude (N) of the net contact force on each patch.
    """
    pair_patch = np.asarray(pair_patch, dtype=int).reshape(-1)
    pair_force_W = np.asarray(pair_force_W, dtype=float).reshape(-1, 3)
    total = np.zeros((num_patches, 3))
    keep = pair_patch >= 0
    np.add.at(total, pair_patch[keep], pair_force_W[keep])
    return np.linalg.norm(total, axis=1)


@dataclass(frozen=True)
class TactileNoise:
    """Binary contact readings from patch forces, with the thesis' error model.

    Attributes:
        force_threshold_n: a patch is truly in contact when its force exceeds this (N).
        false_negative_rate: probability that a patch in contact reads "no contact".
        false_positive_rate_in_contact: probability that a patch not in contact reads
            "contact" while some other patch is in contact.
        false_positive_rate_free: probability that a patch reads "contact" while the hand
            touches nothing (0: perfectly discriminative).
        force_noise_std_n: standard deviation (N) of additive Gaussian noise on the
            reported force magnitudes (clipped at 0).
    """

    force_threshold_n: float = 0.5
    false_negative_rate: float = 0.1
    false_positive_rate_in_contact: float = 0.1
    false_positive_rate_free: float = 0.0
    force_noise_std_n: float = 0.05

    def __post_init__(self) -> None:
        for name in ("false_negative_rate", "false_positive_rate_in_contact",
                     "false_positive_rate_free"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"TactileNoise.{name}={value} is outside [0, 1]")
        # 1 kN: ten times what the hand's motors can press with.
        check_ranges(self, non_negative=("force_threshold_n", "force_noise_std_n"),
                     at_most={"force_threshold_n": 1000.0, "force_noise_std_n": 1000.0})

    @staticmethod
    def noiseless(force_threshold_n: float = 0.5) -> TactileNoise:
        """Readings equal to the true contact state (force above threshold)."""
        return TactileNoise(force_threshold_n, 0.0, 0.0, 0.0, 0.0)

    def true_contact(self, forces_n: np.ndarray) -> np.ndarray:
        """(..., P) bool: which patches carry more than the threshold force."""
        return np.asarray(forces_n) > self.force_threshold_n

    def sample(
        self, forces_n: np.ndarray, *, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """Noisy readings of the patches.

        Args:
            forces_n: (..., P) true force magnitude per patch (N); leading axes are batches.
            rng: random generator (the only source of randomness).

        Returns:
            ``(contact, force)``: (..., P) bool readings and (..., P) noisy force (N).
        """
        forces_n = np.asarray(forces_n, dtype=float)
        touching = self.true_contact(forces_n)
        hand_in_contact = touching.any(axis=-1, keepdims=True)
        flip_probability = np.where(
            touching,
            self.false_negative_rate,
            np.where(hand_in_contact, self.false_positive_rate_in_contact,
                     self.false_positive_rate_free),
        )
        flips = rng.random(forces_n.shape) < flip_probability
        noisy_force = np.maximum(
            forces_n + self.force_noise_std_n * rng.standard_normal(forces_n.shape), 0.0
        )
        return touching ^ flips, noisy_force


@dataclass(frozen=True)
class SensorGroups:
    """Patches pooled into the few binary sensors of a planar model.

    The planning model of thesis ch. 6 has one sensor per finger side (the front of the
    F1/F2 fingers and the front of F3; ``models/assets/planar_sensors/fingertips.yaml``,
    ordered from -y to +y). A group reads contact when the summed force magnitude of its
    patches exceeds the noise model's threshold, and the noise model's errors apply to the
    group, not to each patch: pooling noisy patches instead would multiply the false
    positives of a many-patch group.

    Attributes:
        names: the sensors, in the planar model's order.
        fingers: for each sensor, the fingers whose patches it pools (a patch belongs to a
            finger when its name starts with ``"<finger>_"``).
    """

    names: tuple[str, ...] = ("f12", "f3")
    fingers: tuple[tuple[str, ...], ...] = (("f1", "f2"), ("f3",))

    def __post_init__(self) -> None:
        if len(self.names) != len(self.fingers) or not self.names:
            raise ValueError("SensorGroups needs one finger tuple per sensor name")

    def membership(self, patch_names: tuple[str, ...]) -> np.ndarray:
        """(S, P) 0/1 matrix: which patches each sensor pools.

        Raises:
            ValueError: when a sensor pools no patch of ``patch_names``.
        """
        matrix = np.array([[float(any(p.startswith(f + "_") for f in fingers))
                            for p in patch_names] for fingers in self.fingers])
        empty = [n for n, row in zip(self.names, matrix, strict=True) if not row.any()]
        if empty:
            raise ValueError(f"sensor groups {empty} pool no patch of {list(patch_names)}")
        return matrix
