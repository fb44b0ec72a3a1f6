"""The discrete state space of the hand-relative planning problem (thesis sec. 6.2.2, 6.4.1).

Point-based solvers need discrete states, and a uniform grid blurs exactly what matters:
two poses a millimetre apart behave differently when one touches the hand. The thesis
therefore discretises a *trust region* ``S_trust`` ahead of the hand in two parts:

- free space ``S_trust \\ S_c``: a uniform grid of ``free_cell_m`` x ``free_cell_m`` x
  ``cell_theta_rad`` cells (thesis: 2 cm x 2 cm x 12 deg);
- the contact manifold ``S_trust & S_c``: for each orientation bin, the iso-contour of the
  C-obstacle at the bin's centre angle (the analytic representation of sec. 4.2.2) cut into
  pieces of equal arc length, at most ``contact_cell_m`` (thesis: 1 cm x 12 deg); a contact
  state belongs to the piece its position projects onto;
- one *sentinel* state for every pose outside the trust region (``S \\ S_trust``).

Orientations are folded by the object's rotational symmetry (the box looks the same after
180 deg, so 15 bins of 12 deg cover it; the thesis' 2625 free states are 7 x 25 x 15).

The trust region is a parameter. The thesis' 15 cm x 50 cm cannot hold its own initial
beliefs (means 20 cm ahead with lateral offsets up to +-10 cm and 5 cm standard deviation),
so the default is 40 cm ahead of the palm by 30 cm across; ``trust_x_m=(0, 0.5)``,
``trust_y_m=(-0.075, 0.075)`` restores the thesis' size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from models.config import ConfigError, Fields, resolve_asset
from models.planar.cspace import c_obstacle
from models.planar.world import PlanarWorld
from models.settings import check_ranges

ACTION_NAMES = ("forward", "left", "right", "forward_left", "forward_right")
ACTION_DIRECTIONS = np.array([[1, 0], [0, 1], [0, -1], [1, 1], [1, -1]], dtype=float)


@dataclass(frozen=True)
class HandProblemSpec:
    """Parameters of the hand-relative planning problem (thesis sec. 6.4.1).

    Attributes:
        trust_x_m: (lo, hi) forward extent of the trust region, object centre in the hand
            frame (m; the palm is at x = 0).
        trust_y_m: (lo, hi) lateral extent (m).
        free_cell_m: free-space cell edge (m).
        cell_theta_rad: orientation bin (rad); rounded so the symmetry period divides.
        contact_cell_m: longest contact-manifold piece (m).
        goal_depth_m: goal region depth along x, measured from the hand's front (m).
        goal_width_m: goal region width across, centred on the hand's axis (m).
        step_m: the actions' unit length (m).
        discount: the POMDP discount; the thesis does not give one.
        samples_per_state: Monte Carlo samples per discrete state for T, Z and R.
        action_names: the actions, in order.
        action_directions: each action's planar hand motion in units of ``step_m`` (x
            forward, y left). Default: ch. 6's five (forward, left, right and the two
            forward diagonals: 2 cm and 2 sqrt(2) cm, aligned with the grid); ch. 7 uses
            four 1 cm moves (forward, back, left, right).
        contact_states: separate the contact manifold from free space (ch. 6); without
            (ch. 7, "the simple geometry and high resolution of the discretization made
            doing so unnecessary", sec. 7.3.1) every pose in the trust region falls in its
            grid cell, and the observation model is estimated from where the actions land.
    """

    trust_x_m: tuple[float, float] = (0.0, 0.40)
    trust_y_m: tuple[float, float] = (-0.15, 0.15)
    free_cell_m: float = 0.02
    cell_theta_rad: float = float(np.deg2rad(12.0))
    contact_cell_m: float = 0.01
    goal_depth_m: float = 0.04
    goal_width_m: float = 0.08
    step_m: float = 0.02
    discount: float = 0.95
    samples_per_state: int = 50
    action_names: tuple[str, ...] = ACTION_NAMES
    action_directions: tuple[tuple[float, float], ...] = tuple(
        (float(x), float(y)) for x, y in ACTION_DIRECTIONS)
    contact_states: bool = True

    def __post_init__(self):
        for name in ("trust_x_m", "trust_y_m"):
            lo, hi = getattr(self, name)
            if not hi - lo >= self.free_cell_m:
                raise ValueError(f"{name} must span at least one free cell, got {(lo, hi)}")
        if not 0 < self.free_cell_m <= 0.1 or not 0 < self.contact_cell_m <= 0.1:
            raise ValueError("free_cell_m and contact_cell_m must be in (0, 0.1] m")
        if not 0 < self.cell_theta_rad <= np.pi:
            raise ValueError("cell_theta_rad must be in (0, pi]")
        # Ceilings (m, and steps of step_m): HERB's reach, so that a mistyped exponent is
        # refused rather than discretised into 1e14 cells.
        check_ranges(self, positive=("goal_depth_m", "goal_width_m"),
                     at_most={"trust_x_m": 2.0, "trust_y_m": 2.0, "goal_depth_m": 1.0,
                              "goal_width_m": 1.0, "step_m": 0.5, "action_directions": 10.0})
        if not 0 <= self.discount < 1 or self.samples_per_state < 1 or self.step_m <= 0:
            raise ValueError("discount must be in [0, 1), samples_per_state >= 1, step_m > 0")
        if not self.action_names or len(self.action_names) != len(self.action_directions):
            raise ValueError(f"{len(self.action_names)} action names for "
                             f"{len(self.action_directions)} directions; give one of each")
        if len(set(self.action_names)) != len(self.action_names):
            raise ValueError(f"action names must differ, got {self.action_names}")
        if any(np.hypot(*d) == 0 for d in self.action_directions):
            raise ValueError("every action must move the hand (a direction is zero)")

    @staticmethod
    def load(path) -> HandProblemSpec:
        """Read a problem by built-in name (``models/assets/problems/``: ``rel_ch7``) or
        path; a YAML file whose keys are this class's fields, every one optional: a
        problem file overrides the thesis' ch. 6 problem (``cell_theta_deg`` in degrees;
        ``actions``: a mapping of names to [x, y] directions in units of ``step_m``)."""
        fields = Fields.from_file(resolve_asset("problems", path))
        try:
            return HandProblemSpec._from_fields(fields)
        except ConfigError:
            raise
        except ValueError as err:  # the spec's own checks, which know no file
            raise ConfigError(fields.source, "", str(err)) from None

    @staticmethod
    def _from_fields(fields: Fields) -> HandProblemSpec:
        default = HandProblemSpec()
        names, directions = default.action_names, default.action_directions
        if fields.has("actions"):
            actions = fields.sub("actions")
            names = tuple(actions.keys())
            if not names:
                raise fields.error("actions", "needs at least one action")
            directions = tuple(tuple(actions.vector(name, 2, min=-10.0, max=10.0))
                               for name in names)
            actions.done()
        spec = HandProblemSpec(
            trust_x_m=tuple(fields.vector("trust_x_m", 2, default.trust_x_m)),
            trust_y_m=tuple(fields.vector("trust_y_m", 2, default.trust_y_m)),
            free_cell_m=fields.number("free_cell_m", default.free_cell_m, min=1e-3, max=0.1),
            cell_theta_rad=float(np.deg2rad(fields.number(
                "cell_theta_deg", np.rad2deg(default.cell_theta_rad), min=1.0, max=180.0))),
            contact_cell_m=fields.number("contact_cell_m", default.contact_cell_m,
                                         min=1e-3, max=0.1),
            goal_depth_m=fields.number("goal_depth_m", default.goal_depth_m, min=0.0, max=1.0),
            goal_width_m=fields.number("goal_width_m", default.goal_width_m, min=0.0, max=1.0),
            step_m=fields.number("step_m", default.step_m, min=1e-3, max=0.2),
            discount=fields.number("discount", default.discount, min=0.0, max=0.9999),
            samples_per_state=int(fields.number("samples_per_state", default.samples_per_state,
                                                min=1, max=10_000, integer=True)),
            action_names=names,
            action_directions=directions,
            contact_states=fields.boolean("contact_states", default.contact_states),
        )
        fields.done()
        return spec

    def action_vectors(self) -> np.ndarray:
        """(A, 3) hand motions (dx m, dy m, dtheta rad) in the order of ``action_names``."""
        directions = np.array(self.action_directions, dtype=float)
        return np.column_stack([directions * self.step_m, np.zeros(len(directions))])

    @property
    def max_action_m(self) -> float:
        """Length of the longest action (ch. 6: the diagonals), d_max of sec. 6.3.3."""
        return float(max(np.hypot(*d) for d in self.action_directions) * self.step_m)


def symmetry_order(outline: np.ndarray, tolerance_m: float = 1e-9) -> int:
    """Largest n such that rotating ``outline`` (V, 2) about its origin by 2 pi / n maps
    its vertices onto themselves (1 for an asymmetric outline)."""
    for n in range(len(outline), 1, -1):
        if len(outline) % n:
            continue
        c, s = np.cos(2 * np.pi / n), np.sin(2 * np.pi / n)
        turned = outline @ np.array([[c, s], [-s, c]])
        gaps = np.linalg.norm(turned[:, None, :] - outline[None, :, :], axis=2).min(axis=1)
        if np.all(gaps < tolerance_m):
            return n
    return 1


@dataclass(frozen=True)
class _Contour:
    """One orientation bin's iso-contour, cut into ``count`` pieces of equal length."""

    ring: shapely.LinearRing
    length_m: float
    count: int


@dataclass
class HandDiscretization:
    """Maps continuous object poses (hand frame) to discrete state indices.

    State order: free cells (``ix``, ``iy``, ``k`` in C order), then the contact pieces of
    bin 0, 1, ..., then the sentinel (last index).
    """

    world: PlanarWorld
    spec: HandProblemSpec
    period_rad: float = field(init=False)
    theta_bins: int = field(init=False)
    shape_xy: tuple[int, int] = field(init=False)
    contours: list[_Contour] = field(init=False)
    contact_offsets: np.ndarray = field(init=False)

    def __post_init__(self):
        spec = self.spec
        outline = self.world.shape.vertices[0][self.world.shape.valid[0]]
        self.period_rad = 2 * np.pi / symmetry_order(outline)
        self.theta_bins = max(1, int(round(self.period_rad / spec.cell_theta_rad)))
        nx = int(round((spec.trust_x_m[1] - spec.trust_x_m[0]) / spec.free_cell_m))
        ny = int(round((spec.trust_y_m[1] - spec.trust_y_m[0]) / spec.free_cell_m))
        self.shape_xy = (nx, ny)
        self.contours = []
        for k in range(self.theta_bins if spec.contact_states else 0):
            outer = self._contour(self.bin_centre(k))
            length = float(outer.length)
            self.contours.append(_Contour(outer, length,
                                          max(1, int(np.ceil(length / spec.contact_cell_m)))))
        counts = np.array([c.count for c in self.contours])
        self.contact_offsets = np.concatenate([[0], np.cumsum(counts)])

    def _contour(self, theta: float) -> shapely.LinearRing:
        """The C-obstacle's outer boundary at orientation ``theta`` (holes are pockets no
        object reaches from outside)."""
        outline = self.world.shape.vertices[0][self.world.shape.valid[0]]
        obstacle = c_obstacle(self.world.hand.parts, outline, theta)
        polygons = getattr(obstacle, "geoms", [obstacle])
        return max(polygons, key=lambda p: p.area).exterior

    # -- sizes
    @property
    def free_count(self) -> int:
        return self.shape_xy[0] * self.shape_xy[1] * self.theta_bins

    @property
    def contact_count(self) -> int:
        return int(self.contact_offsets[-1])

    @property
    def sentinel(self) -> int:
        return self.free_count + self.contact_count

    @property
    def state_count(self) -> int:
        return self.sentinel + 1

    def bin_centre(self, k: int) -> float:
        """Orientation (rad) at the centre of bin ``k``."""
        return (k + 0.5) * self.period_rad / self.theta_bins

    def is_contact_state(self, index: np.ndarray) -> np.ndarray:
        index = np.asarray(index)
        return (index >= self.free_count) & (index < self.sentinel)

    # -- the map
    def theta_bin(self, theta: np.ndarray) -> np.ndarray:
        folded = np.mod(theta, self.period_rad)
        return np.minimum((folded / self.period_rad * self.theta_bins).astype(np.int64),
                          self.theta_bins - 1)

    def inside(self, states: np.ndarray) -> np.ndarray:
        """(K,) whether each pose's centre lies in the trust region."""
        (x0, x1), (y0, y1) = self.spec.trust_x_m, self.spec.trust_y_m
        x, y = states[:, 0], states[:, 1]
        return (x >= x0) & (x < x1) & (y >= y0) & (y < y1)

    def index(self, states: np.ndarray) -> np.ndarray:
        """(K,) discrete state of each (K, 3) pose (x m, y m, theta rad)."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        out = np.full(len(states), self.sentinel, dtype=np.int64)
        if len(states) == 0:
            return out
        inside = self.inside(states)
        contact = np.zeros(len(states), dtype=bool)
        if np.any(inside) and self.spec.contact_states:
            contact[inside] = self.world.in_contact(states[inside])
        k = self.theta_bin(states[:, 2])
        free = inside & ~contact
        if np.any(free):
            nx, ny = self.shape_xy
            ix = np.clip(((states[free, 0] - self.spec.trust_x_m[0])
                          // self.spec.free_cell_m).astype(np.int64), 0, nx - 1)
            iy = np.clip(((states[free, 1] - self.spec.trust_y_m[0])
                          // self.spec.free_cell_m).astype(np.int64), 0, ny - 1)
            out[free] = (ix * ny + iy) * self.theta_bins + k[free]
        touching = np.flatnonzero(inside & contact)
        for b in np.unique(k[touching]):  # one Shapely call per orientation bin
            sel = touching[k[touching] == b]
            contour = self.contours[b]
            arc = shapely.line_locate_point(contour.ring, shapely.points(states[sel, :2]))
            piece = np.minimum((arc / contour.length_m * contour.count).astype(np.int64),
                               contour.count - 1)
            out[sel] = self.free_count + self.contact_offsets[b] + piece
        return out

    def state_names(self) -> tuple[str, ...]:
        nx, ny = self.shape_xy
        free = [f"free_{ix}_{iy}_{k}" for ix in range(nx) for iy in range(ny)
                for k in range(self.theta_bins)]
        contact = [f"contact_{k}_{p}" for k, c in enumerate(self.contours)
                   for p in range(c.count)]
        return tuple(free + contact + ["outside"])

    def representative_poses(self) -> np.ndarray:
        """(S - 1, 3) a pose in each non-sentinel state (cell centre, piece midpoint)."""
        nx, ny = self.shape_xy
        ix, iy, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(self.theta_bins),
                                indexing="ij")
        c = self.spec.free_cell_m
        free = np.column_stack([self.spec.trust_x_m[0] + (ix.ravel() + 0.5) * c,
                                self.spec.trust_y_m[0] + (iy.ravel() + 0.5) * c,
                                [self.bin_centre(b) for b in k.ravel()]])
        pieces = []
        for b, contour in enumerate(self.contours):
            arc = (np.arange(contour.count) + 0.5) / contour.count * contour.length_m
            xy = shapely.get_coordinates(shapely.line_interpolate_point(contour.ring, arc))
            pieces.append(np.column_stack([xy, np.full(contour.count, self.bin_centre(b))]))
        return np.vstack([free, *pieces])

    # -- uniform samples within states (the Monte Carlo of sec. 6.2.2)
    def sample_free(self, per_state: int, *, rng: np.random.Generator,
                    oversample: int = 4) -> tuple[np.ndarray, np.ndarray]:
        """Up to ``per_state`` poses drawn uniformly in each free cell: outside contact when
        the contact manifold has states of its own, else anywhere the object does not
        overlap the hand (a cell then holds its contact poses too, as :meth:`index` maps
        them: a cell along the hand whose only room lies within the sensors' contact
        tolerance, where a pushed object rests, is kept rather than dropped).

        Returns:
            (M, 3) poses and (M,) their state index; cells entirely inside the hand get none.
        """
        nx, ny = self.shape_xy
        draws = per_state * oversample
        cell = np.repeat(np.arange(self.free_count), draws)
        ixy, k = np.divmod(cell, self.theta_bins)
        ix, iy = np.divmod(ixy, ny)
        u = rng.random((len(cell), 3))
        c = self.spec.free_cell_m
        poses = np.column_stack([
            self.spec.trust_x_m[0] + (ix + u[:, 0]) * c,
            self.spec.trust_y_m[0] + (iy + u[:, 1]) * c,
            (k + u[:, 2]) * self.period_rad / self.theta_bins])
        ok = (~self.world.in_contact(poses) if self.spec.contact_states
              else self.world.overlap_free(poses))
        poses, cell = poses[ok], cell[ok]
        return _first_per_state(poses, cell, per_state)

    def sample_contact(self, per_state: int, *, rng: np.random.Generator,
                       levels_per_bin: int = 24, oversample: int = 3
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Up to ``per_state`` poses on the contact manifold in each contact piece.

        Poses are drawn uniformly by arc length on iso-contours at ``levels_per_bin``
        orientations per bin (with jitter inside the level's slice), then classified by
        :meth:`index`; this is uniform over the states that map to each piece.
        """
        if not self.contours:  # no contact states (``contact_states=False``)
            return np.empty((0, 3)), np.empty(0, dtype=np.int64)
        width = self.period_rad / self.theta_bins
        poses = []
        for b, contour in enumerate(self.contours):
            n_level = int(np.ceil(contour.count * per_state * oversample / levels_per_bin))
            for j in range(levels_per_bin):
                theta = (b + (j + 0.5) / levels_per_bin) * width
                ring = self._contour(theta)
                arc = rng.random(n_level) * ring.length
                xy = shapely.get_coordinates(shapely.line_interpolate_point(ring, arc))
                jitter = (rng.random(n_level) - 0.5) * width / levels_per_bin
                poses.append(np.column_stack([xy, theta + jitter]))
        poses = np.vstack(poses)
        state = self.index(poses)
        keep = self.is_contact_state(state)
        return _first_per_state(poses[keep], state[keep], per_state)


def _first_per_state(poses: np.ndarray, state: np.ndarray,
                     per_state: int) -> tuple[np.ndarray, np.ndarray]:
    """Keep at most ``per_state`` poses of each state (the first drawn), grouped by state."""
    order = np.argsort(state, kind="stable")
    poses, state = poses[order], state[order]
    first = np.searchsorted(state, state, side="left")
    keep = np.arange(len(state)) - first < per_state
    return poses[keep], state[keep]
