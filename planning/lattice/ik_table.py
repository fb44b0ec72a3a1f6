"""The lattice's arm configurations ``q_lat(x_r)``, solved once per robot and table and
cached on disk (thesis sec. 7.2.1, "hybrid" evaluation).

Each lattice point gets one inverse-kinematics solution from Drake's ``InverseKinematics``
(:class:`~models.herb.kinematics.PlanarHandIK`: joint limits, palm pose within 0.1 mm and
1 mrad, clearance from the table and the robot itself), solved in breadth-first order from
the start point, each seeded with the solution of the neighbour it was reached from, so
that neighbours stay close in joint space (thesis sec. 7.3.1: "an iterative inverse
kinematics solver initialised with the configuration of an adjacent lattice point"). A
point whose solve fails gets none, and the search does not continue through it; points
only reachable through failed ones get none either (``unreached``). A point whose palm is
off the table top gets none (``off the table``).

What this table depends on is the robot, the table and the lattice, not the obstacles:
they are left out of the kinematic model here and checked per scene, lazily
(:mod:`planning.lattice.lattice`). So the table is solved once (about 10 s for the default
51 x 81 points, 2 ms a solve) and stored as ``<cache_dir>/lattice/<key>.npz``, ``key``
a hash of everything it depends on (the robot's model files, the arm, the table, the
palm's height, the lattice, the IK's clearance and posture weight, Drake's version).
"""

from __future__ import annotations

import hashlib
import json
from collections import deque
from dataclasses import asdict, dataclass, replace
from importlib.metadata import version
from pathlib import Path

import numpy as np
from tqdm import tqdm

from models.config import ASSETS_DIR
from models.herb.kinematics import PlanarHandIK
from models.herb.mount import NUM_ARM_JOINTS
from models.herb.scene import SceneSpec
from planning.lattice.grid import LatticeSpec

#: The robot's model files: the table's cache key hashes their contents.
ROBOT_FILES = ("wam7.sdf", "barrett_hand.yaml", "herb.yaml")
#: The IK's pull towards HERB's home posture (see :class:`PlanarHandIK`): as the closed
#: loop's, so that the lattice's start configuration is the episode's.
POSTURE_WEIGHT = 0.05
#: Clearance (m) the IK keeps from the table and the robot itself.
IK_CLEARANCE_M = 0.005


@dataclass(frozen=True)
class IKTable:
    """One arm configuration per lattice point.

    Attributes:
        spec: the lattice.
        q: (P, 7) arm joint angles (rad); NaN rows where the point has none.
        reasons: (P,) why a point has none ('' where it has one).
        key: the cache key it was stored under.
    """

    spec: LatticeSpec
    q: np.ndarray
    reasons: tuple[str, ...]
    key: str

    @property
    def reachable(self) -> np.ndarray:
        """(P,) bool: the points with a configuration."""
        return ~np.isnan(self.q[:, 0])


def surface_scene(scene: SceneSpec) -> SceneSpec:
    """The scene without its obstacles: what the IK table depends on."""
    return replace(scene, obstacles=())


def cache_key(scene: SceneSpec, spec: LatticeSpec) -> str:
    """A hash of everything the IK table depends on (see the module docstring)."""
    digest = hashlib.sha256()
    for name in ROBOT_FILES:
        digest.update((ASSETS_DIR / name).read_bytes())
    digest.update(json.dumps({
        "arm": scene.arm, "table": asdict(scene.table), "hand_height_m": scene.hand_height_m,
        "lattice": asdict(spec), "clearance_m": IK_CLEARANCE_M,
        "posture_weight": POSTURE_WEIGHT, "drake": version("drake"),
    }, sort_keys=True, default=list).encode())
    return digest.hexdigest()[:20]


def solve_ik_table(scene: SceneSpec, spec: LatticeSpec, *, progress: bool = True) -> IKTable:
    """Solve every lattice point (breadth-first from the start; see the module docstring).

    Raises:
        ValueError: the start pose itself has no IK solution.
    """
    ik = PlanarHandIK(surface_scene(scene), clearance_m=IK_CLEARANCE_M,
                      posture_weight=POSTURE_WEIGHT)
    table = scene.table
    poses = spec.poses(np.arange(spec.size))
    q = np.full((spec.size, NUM_ARM_JOINTS), np.nan)
    reasons = ["unreached: every path to it from the start crosses a point without IK"] * spec.size
    first = ik.solve_multistart(np.asarray(spec.start, dtype=float),
                                rng=np.random.default_rng(0))
    if not first.feasible:
        raise ValueError(f"the lattice's start pose {spec.start} has no IK solution: "
                         f"{first.reason}")
    start = spec.start_point
    q[start], reasons[start] = first.q, ""
    visited = np.zeros(spec.size, dtype=bool)
    visited[start] = True
    queue = deque([start])
    steps = ((1, 0), (-1, 0), (0, 1), (0, -1))
    bar = tqdm(total=spec.size, desc="lattice IK", unit="point", disable=not progress)
    bar.update()
    while queue:
        point = queue.popleft()
        ix, iy = spec.offsets(point)
        for dx, dy in steps:
            neighbour = int(spec.point(ix + dx, iy + dy))
            if neighbour < 0 or visited[neighbour]:
                continue
            visited[neighbour] = True
            bar.update()
            x, y, _ = poses[neighbour]
            if not table.contains(x, y):
                reasons[neighbour] = "off the table: the palm is not over the table top"
                continue
            result = ik.solve(poses[neighbour], q[point])
            if result.feasible:
                q[neighbour], reasons[neighbour] = result.q, ""
                queue.append(neighbour)
            else:
                reasons[neighbour] = result.reason
    bar.close()
    return IKTable(spec, q, tuple(reasons), cache_key(scene, spec))


def load_ik_table(scene: SceneSpec, spec: LatticeSpec, *, cache_dir: Path | None,
                  progress: bool = True) -> IKTable:
    """The IK table from ``<cache_dir>/lattice/<key>.npz``, solved and stored there when
    missing (``cache_dir`` None: solved, not stored)."""
    key = cache_key(scene, spec)
    path = None if cache_dir is None else Path(cache_dir) / "lattice" / f"{key}.npz"
    if path is not None and path.exists():
        data = np.load(path)
        return IKTable(spec, data["q"], tuple(str(r) for r in data["reasons"]), key)
    table = solve_ik_table(scene, spec, progress=progress)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_suffix(".part.npz")
        np.savez_compressed(partial, q=table.q, reasons=np.array(table.reasons))
        partial.replace(path)  # atomic: a killed run never leaves a half-written table
    return table
