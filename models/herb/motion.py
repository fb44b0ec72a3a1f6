"""One hand-relative action as an arm motion: the IK executor of the closed loop.

The planners act in the hand frame: an action is a planar displacement (dx forward, dy
left, dtheta) of the palm (thesis sec. 6.4.1: five 2 cm translations). Executing it means
solving the arm's inverse kinematics along the straight palm path in the world, every
``step_m``, each pose warm-started from the last (:class:`~models.herb.kinematics.PlanarHandIK`,
with joint limits and clearance from the table, the obstacles and the robot itself). An
action is *feasible* when every pose along the way is, and when the palm stays over the
table by ``table_margin_m``; an infeasible action is reported with the reason and never
clipped.

Controllers ask whether an action is feasible before they send it, and the executor then
needs the same joint path; the last few answers are kept, so the second request is free.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Protocol

import numpy as np

from models.herb.kinematics import JointPath, PlanarHandIK, solve_chain
from models.se2 import compose

CACHE_SIZE = 32


class MotionPlanner(Protocol):
    """What the closed loop's controller and executor need of a motion planner: the joint
    path of a hand-frame action (:class:`HandMotionPlanner`: IK along the straight palm
    path; :class:`planning.lattice.motion.LatticeMotion`: the lattice's edge), and the
    kinematic model whose velocity limits time it."""

    ik: PlanarHandIK

    def plan(self, pose_W: np.ndarray, q: np.ndarray, action_H: np.ndarray) -> JointPath:
        """The joint path that moves the palm by ``action_H`` from ``pose_W`` and ``q``."""


def world_target(pose_W: np.ndarray, action_H: np.ndarray) -> np.ndarray:
    """The palm's planar world pose (3,) after the hand-frame displacement ``action_H``
    (dx m, dy m, dtheta rad) from ``pose_W`` (x m, y m, theta rad)."""
    return compose(np.asarray(pose_W, dtype=float), np.asarray(action_H, dtype=float))


class HandMotionPlanner:
    """Joint paths of hand-frame actions.

    Args:
        ik: the scene's inverse kinematics.
        step_m: palm travel between IK solutions (m); the executor interpolates between
            them, so this bounds how far the palm can stray from the straight line.
        table_margin_m: how far inside the table's edge the palm must stay (m).
    """

    def __init__(self, ik: PlanarHandIK, *, step_m: float = 0.005,
                 table_margin_m: float = 0.0):
        if step_m <= 0:
            raise ValueError(f"step_m must be > 0 m, got {step_m}")
        self.ik = ik
        self.step_m = step_m
        self.table_margin_m = table_margin_m
        self._cache: OrderedDict[tuple, JointPath] = OrderedDict()

    def plan(self, pose_W: np.ndarray, q: np.ndarray, action_H: np.ndarray) -> JointPath:
        """The joint path that moves the palm by ``action_H`` from ``pose_W``.

        Args:
            pose_W: (3,) the palm's planar world pose now (x m, y m, theta rad).
            q: (7,) the arm's joint angles now (rad); the path starts there.
            action_H: (3,) the displacement in the hand frame (m, m, rad).

        Returns:
            ``poses`` (N + 1, 3) and ``q`` (N + 1, 7) from the start, or up to the first
            infeasible pose with ``feasible=False`` and the reason.
        """
        pose_W, q = np.asarray(pose_W, dtype=float), np.asarray(q, dtype=float)
        action_H = np.asarray(action_H, dtype=float)
        key = (tuple(np.round(pose_W, 7)), tuple(np.round(q, 7)), tuple(np.round(action_H, 7)))
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        path = self._solve(pose_W, q, action_H)
        self._cache[key] = path
        if len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
        return path

    def _solve(self, pose_W, q, action_H) -> JointPath:
        length = max(float(np.linalg.norm(action_H[:2])), 1e-12)
        count = max(1, int(np.ceil(length / self.step_m - 1e-9)))
        targets = world_target(pose_W, action_H * (np.arange(1, count + 1) / count)[:, None])
        table = self.ik.world.scene.table
        on_table = [table.contains(x, y, self.table_margin_m) for x, y, _ in targets]
        leaves = on_table.index(False) if not all(on_table) else count
        path = solve_chain(self.ik, pose_W, q, targets[:leaves])
        if not path.feasible or leaves == count:
            return path
        x, y = targets[leaves, :2]
        return JointPath(path.poses, path.q, False,
                         f"the palm would leave the table at ({x:.3f}, {y:.3f}) m")
