"""The configuration lattice of one scene, evaluated lazily (thesis sec. 7.1, 7.2.1).

A lattice point's configuration comes from the scene-independent IK table
(:mod:`planning.lattice.ik_table`); everything that depends on the scene's obstacles is
computed only when a planner asks, and then kept (in memory, for every later scenario,
trial and decision):

- a point is *free* when its configuration is collision-free in the scene;
- the local planner ``psi(q_lat(x_r), a_lat)`` of an action template is the straight line
  in joint space between the two points' configurations (thesis sec. 7.3.1: at 1 cm the
  lattice is dense enough for it). It is feasible when both ends are free, the palm stays
  on the template's Cartesian motion within ``path_tolerance_m`` and
  ``heading_tolerance_rad`` (forward kinematics at every interpolated configuration), and
  every interpolated configuration, at most ``joint_step_rad`` apart in every joint, is
  collision-free against the table, HERB's body, the obstacles and the robot itself
  (Drake's ``SceneGraphCollisionChecker``, all the configurations of the edges asked for
  at once in one batched call).

Drake's signed-distance query gives each evaluated edge its clearance: the smallest
signed distance between a robot geometry and anything else along it (``CalcRobotClearance``
within 10 cm), so a planner or a drawing can say how close the arm passes to an obstacle.
The evaluated fraction of the lattice (the thesis' Fig. 7.1) is
:meth:`ConfigurationLattice.stats`; the edges one episode asked for,
:attr:`ConfigurationLattice.asked`.

Why Drake's collision checker rather than the IK's distance query: it checks a batch of
configurations in one call, filters the robot's adjacent links once, and is what the
planning community uses for edge checks; its padding (``padding_m``) is the margin kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.planning import CollisionCheckerParams, SceneGraphCollisionChecker

from models.herb.kinematics import PlanarHandIK, robot_diagram
from models.herb.scene import SceneSpec
from models.pose import wrap_angle
from planning.lattice.ik_table import IKTable

UNKNOWN, INFEASIBLE, FEASIBLE = -1, 0, 1
#: Influence distance (m) of the clearance query: farther pairs are not reported.
CLEARANCE_INFLUENCE_M = 0.10


@dataclass(frozen=True)
class Edge:
    """One evaluated edge: action template ``action`` from lattice point ``point``.

    Attributes:
        point, action, target: the start point, the template and the end point (-1 when
            it is off the lattice).
        feasible: whether the local planner found the motion.
        q: (N, 7) the joint path (rad), start to end (the interpolated configurations);
            empty when an end has no configuration.
        poses: (N, 4) the palm's planar pose (x m, y m, theta rad) and height (m) at each.
        reason: why it is infeasible ('' when feasible).
    """

    point: int
    action: int
    target: int
    feasible: bool
    q: np.ndarray
    poses: np.ndarray
    reason: str = ""


@dataclass(frozen=True)
class LatticeStats:
    """How much of the lattice has been evaluated (thesis Fig. 7.1).

    Attributes:
        points, edges: the lattice's points P and edges P x A.
        points_evaluated, edges_evaluated: those checked in the scene so far.
        edges_feasible: evaluated edges found feasible.
    """

    points: int
    edges: int
    points_evaluated: int
    edges_evaluated: int
    edges_feasible: int

    @property
    def edge_fraction(self) -> float:
        return self.edges_evaluated / self.edges


class ConfigurationLattice:
    """The lattice of one scene (see the module docstring).

    Args:
        scene: the scene (its obstacles are what is checked lazily).
        table: the IK table of the scene's robot and table.
        action_vectors: (A, 3) the action templates (hand frame, m, m, rad).
        joint_step_rad: largest joint change between checked configurations of an edge.
        path_tolerance_m: how far the palm may leave the template's straight motion (m).
        heading_tolerance_rad: how far the palm may turn from the lattice's heading.
        padding_m: margin the collision checker keeps between the robot and everything
            else (m); below the IK's 5 mm clearance, so that a point the IK accepted next
            to the table is not refused for the table.
    """

    def __init__(self, scene: SceneSpec, table: IKTable, action_vectors: np.ndarray, *,
                 joint_step_rad: float = 0.01, path_tolerance_m: float = 0.002,
                 heading_tolerance_rad: float = float(np.deg2rad(1.0)),
                 padding_m: float = 0.002):
        self.scene = scene
        self.table = table
        self.spec = table.spec
        self.action_vectors = np.asarray(action_vectors, dtype=float)
        self.neighbours = self.spec.neighbours(self.action_vectors)
        self.joint_step_rad = joint_step_rad
        self.path_tolerance_m = path_tolerance_m
        self.heading_tolerance_rad = heading_tolerance_rad
        self.kinematics = PlanarHandIK(scene)  # forward kinematics and named close pairs
        diagram, world = robot_diagram(scene)
        params = CollisionCheckerParams()
        params.model = diagram
        params.robot_model_instances = [world.wam, world.hand.instance]
        params.edge_step_size = joint_step_rad
        params.env_collision_padding = padding_m
        params.self_collision_padding = 0.0
        self.checker = SceneGraphCollisionChecker(params)
        self.poses = self.spec.poses(np.arange(self.spec.size))
        size, actions = self.spec.size, len(self.action_vectors)
        self.status = np.full((size, actions), UNKNOWN, dtype=np.int8)
        self._point_free = np.full(size, UNKNOWN, dtype=np.int8)
        self._edges: dict[tuple[int, int], Edge] = {}
        self._clearances: dict[tuple[int, int], float] = {}
        #: (P, A) bool: the edges asked for since :meth:`reset_asked` (what one episode
        #: or decision needed, whatever was evaluated before it).
        self.asked = np.zeros((size, actions), dtype=bool)

    @property
    def start_point(self) -> int:
        return self.spec.start_point

    def full_positions(self, q_arm: np.ndarray) -> np.ndarray:
        return self.kinematics.full_positions(q_arm)

    def feasible(self, points: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """(K,) bool: is template ``actions[k]`` feasible from lattice point ``points[k]``?
        Evaluates (in one batch) the pairs not evaluated before, and only those."""
        points = np.asarray(points, dtype=np.int64)
        actions = np.asarray(actions, dtype=np.int64)
        self.asked[points, actions] = True
        status = self.status[points, actions]
        unknown = status == UNKNOWN
        if unknown.any():
            pairs = np.unique(np.stack([points[unknown], actions[unknown]], axis=1), axis=0)
            self._evaluate([tuple(map(int, p)) for p in pairs])
            status = self.status[points, actions]
        return status == FEASIBLE

    def feasible_actions(self, point: int) -> np.ndarray:
        """(A,) bool: which templates are feasible from ``point`` (evaluating them all)."""
        count = len(self.action_vectors)
        return self.feasible(np.full(count, point), np.arange(count))

    def reset_asked(self) -> None:
        """Forget which edges were asked for (not their evaluation)."""
        self.asked[:] = False

    def edge(self, point: int, action: int) -> Edge:
        """The edge of template ``action`` from ``point`` (evaluated if it was not)."""
        self.asked[point, action] = True
        if self.status[point, action] == UNKNOWN:
            self._evaluate([(int(point), int(action))])
        return self._edges[(int(point), int(action))]

    def clearance(self, point: int, action: int) -> float:
        """The smallest signed distance (m) between a robot geometry and anything else
        along the edge's joint path (capped at 0.1 m; negative: penetration; NaN when no
        path was built: an end without a configuration or colliding), from Drake's
        signed-distance query; kept once asked."""
        key = (int(point), int(action))
        if key not in self._clearances:
            q = self.edge(point, action).q
            self._clearances[key] = (min(self._clearance(qk) for qk in q) if len(q)
                                     else float("nan"))
        return self._clearances[key]

    def evaluated_edges(self) -> list[Edge]:
        """Every edge evaluated so far."""
        return list(self._edges.values())

    def stats(self) -> LatticeStats:
        return LatticeStats(self.spec.size, self.status.size,
                            int(np.count_nonzero(self._point_free != UNKNOWN)),
                            int(np.count_nonzero(self.status != UNKNOWN)),
                            int(np.count_nonzero(self.status == FEASIBLE)))

    def point_free(self, points: np.ndarray) -> np.ndarray:
        """(K,) bool: does each point have a configuration that is collision-free in the
        scene? Checks the points not checked before (in one batch)."""
        points = np.atleast_1d(np.asarray(points, dtype=np.int64))
        todo = np.unique(points[self._point_free[points] == UNKNOWN])
        if len(todo):
            reachable = self.table.reachable[todo]
            free = np.zeros(len(todo), dtype=bool)
            if reachable.any():
                configs = [self.full_positions(q) for q in self.table.q[todo[reachable]]]
                free[reachable] = self.checker.CheckConfigsCollisionFree(configs)
            self._point_free[todo] = np.where(free, FEASIBLE, INFEASIBLE)
        return self._point_free[points] == FEASIBLE

    def _evaluate(self, pairs: list[tuple[int, int]]) -> None:
        """Run the local planner on ``pairs`` of (point, action); see the module docstring."""
        targets = [int(self.neighbours[p, a]) for p, a in pairs]
        ends = np.array([x for (p, _), t in zip(pairs, targets, strict=True)
                         for x in (p, t) if x >= 0], dtype=np.int64)
        if len(ends):
            self.point_free(ends)
        paths, checks = {}, []
        for (point, action), target in zip(pairs, targets, strict=True):
            reason = self._end_reason(point, target)
            if reason:
                self._store(Edge(point, action, target, False, np.zeros((0, 7)),
                                 np.zeros((0, 4)), reason))
                continue
            q0, q1 = self.table.q[point], self.table.q[target]
            count = max(1, int(np.ceil(np.max(np.abs(q1 - q0)) / self.joint_step_rad)))
            q = q0 + np.linspace(0.0, 1.0, count + 1)[:, None] * (q1 - q0)
            paths[(point, action)] = (target, q)
            checks.extend((point, action, k) for k in range(1, count))
        if not paths:
            return
        configs = [self.full_positions(paths[(p, a)][1][k]) for p, a, k in checks]
        free = self.checker.CheckConfigsCollisionFree(configs) if configs else []
        collides = {(p, a) for (p, a, _), ok in zip(checks, free, strict=True) if not ok}
        for (point, action), (target, q) in paths.items():
            poses = np.array([self.kinematics.palm_pose(qk) for qk in q])
            reason = self._path_reason(point, target, poses)
            if not reason and (point, action) in collides:
                reason = self._collision_reason(q)
            self._store(Edge(point, action, target, not reason, q, poses, reason))

    def _store(self, edge: Edge) -> None:
        self._edges[(edge.point, edge.action)] = edge
        self.status[edge.point, edge.action] = FEASIBLE if edge.feasible else INFEASIBLE

    def _end_reason(self, point: int, target: int) -> str:
        if target < 0:
            return "the motion leaves the lattice"
        for label, p in (("start", point), ("end", target)):
            if not self.table.reachable[p]:
                return f"the {label} point has no IK solution: {self.table.reasons[p]}"
            if not self._point_free[p] == FEASIBLE:
                return (f"the {label} point's configuration collides in the scene: "
                        + self._collision_reason(self.table.q[p][None]))
        return ""

    def _path_reason(self, point: int, target: int, poses: np.ndarray) -> str:
        """Why the palm leaves the template's straight motion ('' when it does not)."""
        a, b = self.poses[point, :2], self.poses[target, :2]
        direction = (b - a) / np.linalg.norm(b - a)
        offset = poses[:, :2] - a
        along = np.clip(offset @ direction, 0.0, np.linalg.norm(b - a))
        lateral = np.linalg.norm(offset - along[:, None] * direction, axis=1)
        height = np.abs(poses[:, 3] - poses[0, 3])
        deviation = float(np.max(np.hypot(lateral, height)))
        heading = float(np.max(np.abs(wrap_angle(poses[:, 2] - self.poses[point, 2]))))
        if deviation > self.path_tolerance_m:
            return (f"the palm leaves the straight motion by {deviation * 1e3:.2f} mm "
                    f"(tolerance {self.path_tolerance_m * 1e3:.2f} mm)")
        if heading > self.heading_tolerance_rad:
            return (f"the palm turns by {np.rad2deg(heading):.2f} deg (tolerance "
                    f"{np.rad2deg(self.heading_tolerance_rad):.2f} deg)")
        return ""

    def _clearance(self, q_arm: np.ndarray) -> float:
        """The scene's smallest robot signed distance at ``q_arm`` (m; Drake's QueryObject,
        pairs within 10 cm)."""
        return self.kinematics.min_distance(q_arm, CLEARANCE_INFLUENCE_M)

    def _collision_reason(self, q: np.ndarray) -> str:
        """Names what the deepest configuration of ``q`` (N, 7) hits."""
        depths = [self._clearance(qk) for qk in q]
        deepest = q[int(np.argmin(depths))]
        pairs = self.kinematics.close_pairs(deepest, self.checker.GetLargestPadding())
        what = pairs[0].describe(0.0) if pairs else "robot geometry in collision"
        return f"collision: {what}"
