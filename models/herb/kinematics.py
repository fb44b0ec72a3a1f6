"""Moving the hand the way the planners will: planar hand poses to arm configurations.

An action is a planar motion of the palm at a fixed height above the table with a fixed
orientation (thesis eq. 7.1): the palm faces the push direction theta, F3 on the left.
:class:`PlanarHandIK` turns a planar pose (x, y, theta) into the 7 arm joint angles with
Drake's ``InverseKinematics``, respecting joint limits and keeping every robot geometry
at least ``clearance_m`` from the table, the obstacles and the robot itself. The movable
object is *not* in the kinematic model: the hand is meant to touch it.

Each solve runs in two stages, because SNOPT with the non-convex minimum-distance
constraint fails from poor seeds far more often than without it:
(1) pose constraints only, from the seed, minimising the distance to the seed; (2) only
when (1)'s answer lacks clearance: pose plus clearance, from (1)'s answer, staying near it.
Every answer is verified by forward kinematics and a distance query. A chain of nearby
poses (a push, a lattice) warm-starts into a smooth joint path. A target that neither
stage satisfies is reported as infeasible with the reason; it is never clipped to a
nearby reachable pose. The reason is ``unreachable`` when stage (1) finds no joint
solution within the limits, and ``collision`` when the pose is reached only closer than
``clearance_m`` to something: the message then names the robot link and geometry and what
it hits (an obstacle by its scene name, the table, HERB's torso or another link), from
Drake's signed-distance query at the pose-only solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.planning import RobotDiagram, RobotDiagramBuilder
from pydrake.solvers import Solve

from models.herb.mount import NUM_ARM_JOINTS, planar_palm_pose
from models.herb.scene import SceneSpec
from models.herb.tactile import TactileLayout
from models.herb.world import HerbWorld, populate_world
from models.pose import wrap_angle

POSITION_TOLERANCE_M = 1e-4
ORIENTATION_TOLERANCE_RAD = 1e-3
#: How much a clearance-constrained answer may fall short of ``clearance_m`` (m).
CLEARANCE_SLACK_M = 1e-4


def format_mm(value_m: float, reference_m: float) -> str:
    """``value_m`` in millimetres, with 2 decimals or as many more (up to 6) as it takes to
    differ from ``reference_m`` printed the same way (so that 4.9996 mm never prints as the
    5.00 mm it falls short of)."""
    for digits in range(2, 7):
        text = f"{value_m * 1e3:.{digits}f}"
        if text != f"{reference_m * 1e3:.{digits}f}":
            return text
    return text


@dataclass(frozen=True)
class ClosePair:
    """A robot geometry and another geometry closer than the clearance.

    Attributes:
        distance_m: signed distance (m) between them; negative when they penetrate.
        robot_link: the robot's body (e.g. ``"bh_base"``, ``"wam6"``).
        robot_geometry: its collision geometry (e.g. ``"palm_pad"``).
        other: the other body: an obstacle's name in the scene, ``"table"``,
            ``"herb_torso"``, or another robot link (self-collision).
        other_geometry: the other body's collision geometry.
        other_kind: ``"obstacle"``, ``"robot link"`` or ``"environment body"``.
    """

    distance_m: float
    robot_link: str
    robot_geometry: str
    other: str
    other_geometry: str
    other_kind: str

    def describe(self, clearance_m: float) -> str:
        """E.g. ``robot link 'bh_base' (geometry 'palm_pad') penetrates obstacle
        'cracker_box' by 58.92 mm`` or ``robot link 'wam6' (geometry 'wam6_collision_0') is
        4.87 mm from environment body 'table' (geometry 'table_top')``; distances in mm
        with enough digits to differ from ``clearance_m`` (see :func:`format_mm`)."""
        robot = f"robot link '{self.robot_link}' (geometry '{self.robot_geometry}')"
        other = f"{self.other_kind} '{self.other}'"
        if self.other_geometry != self.other:
            other += f" (geometry '{self.other_geometry}')"
        if self.distance_m < 0:
            return f"{robot} penetrates {other} by {format_mm(-self.distance_m, 0.0)} mm"
        return f"{robot} is {format_mm(self.distance_m, clearance_m)} mm from {other}"


@dataclass(frozen=True)
class IKResult:
    """Outcome of one inverse-kinematics query.

    Attributes:
        feasible: whether ``q`` reaches the pose within tolerance, inside the joint
            limits, with the required clearance.
        q: (7,) arm joint angles (rad); the last attempt's answer when infeasible.
        reason: empty when feasible; otherwise why not, starting with ``unreachable``
            (no joint solution within the limits reaches the pose) or ``collision`` (the
            pose is reached only closer than the clearance to something; names what).
        min_distance_m: smallest signed distance between robot and environment/self at
            ``q`` (m), over pairs closer than 0.1 m (0.1 when none is that close).
        blocking: for a collision, the pairs closer than the clearance at the solution
            that reaches the pose, closest (deepest) first; empty otherwise.
    """

    feasible: bool
    q: np.ndarray
    reason: str = ""
    min_distance_m: float = 0.1
    blocking: tuple[ClosePair, ...] = ()


def robot_diagram(scene: SceneSpec) -> tuple[RobotDiagram, HerbWorld]:
    """A kinematic model of ``scene`` without its movable object (the hand is meant to
    touch it): HERB's arm and hand (fingertip tactile patches), the table, HERB's body and
    the obstacles, as the ``RobotDiagram`` that Drake's IK and collision checkers take."""
    builder = RobotDiagramBuilder(time_step=0.0)
    plant = builder.plant()
    world = populate_world(plant, builder.scene_graph(), scene,
                           layout=TactileLayout.load("fingertips"), include_object=False)
    plant.Finalize()
    return builder.Build(), world


class PlanarHandIK:
    """Inverse kinematics of HERB's arm for planar hand poses in one scene.

    Args:
        scene: the scene (robot mount, table, obstacles; its movable object is ignored).
        clearance_m: minimum distance (m) kept between robot geometry and the table,
            the obstacles and the robot itself.
        posture_weight: weight of a pull towards HERB's home configuration, relative to
            the pull towards the seed (0: none). A chain of warm-started solves otherwise
            drifts wherever the seed leads and can end folded against a joint limit or the
            robot's body with the target still reachable from another posture; a small
            pull keeps the arm in the middle of its workspace (the null-space posture task
            of a redundant arm's controller).
    """

    def __init__(self, scene: SceneSpec, *, clearance_m: float = 0.005,
                 posture_weight: float = 0.0):
        if posture_weight < 0:
            raise ValueError(f"posture_weight must be >= 0, got {posture_weight}")
        self._diagram, self.world = robot_diagram(scene)
        plant = self._diagram.plant()
        self.plant = plant
        self._context = self._diagram.CreateDefaultContext()
        self._plant_context = plant.GetMyMutableContextFromRoot(self._context)
        self.clearance_m = clearance_m
        self.posture_weight = posture_weight
        self._q_full = self.world.robot_positions(plant, np.zeros(NUM_ARM_JOINTS))
        start = plant.GetJointByName("wam_j1", self.world.wam).position_start()
        self._arm_slice = slice(start, start + NUM_ARM_JOINTS)
        self.lower = plant.GetPositionLowerLimits()[self._arm_slice]
        self.upper = plant.GetPositionUpperLimits()[self._arm_slice]
        self.velocity_limits = plant.GetVelocityUpperLimits()[self._arm_slice]
        self.home = self.world.mount.home[scene.arm].copy()

    def full_positions(self, q_arm: np.ndarray) -> np.ndarray:
        """The plant's full position vector (arm plus hand preshape) for arm angles (7,)."""
        q = self._q_full.copy()
        q[self._arm_slice] = q_arm
        return q

    def palm_pose(self, q_arm: np.ndarray) -> np.ndarray:
        """Forward kinematics: (x, y, theta) of the palm for arm angles (7,), and its height."""
        self.plant.SetPositions(self._plant_context, self.full_positions(q_arm))
        X = self.world.hand.palm_frame.CalcPoseInWorld(self._plant_context)
        return np.append(planar_palm_pose(X), X.translation()[2])

    def solve(self, pose: np.ndarray, seed: np.ndarray) -> IKResult:
        """Arm angles that put the palm at planar ``pose`` (x m, y m, theta rad).

        Args:
            pose: (3,) target planar pose.
            seed: (7,) initial guess; the solution minimises the distance to it.
        """
        seed = np.clip(np.asarray(seed, dtype=float), self.lower, self.upper)
        ok, q_pose = self._solve_once(pose, seed, with_clearance=False)
        if not (ok or self._reaches(q_pose, pose)):
            return IKResult(False, q_pose, "unreachable: no joint solution within limits near "
                                           "the seed reaches the pose")
        min_distance = self.min_distance(q_pose)
        if min_distance >= self.clearance_m:
            return IKResult(True, q_pose, "", min_distance)
        ok, q = self._solve_once(pose, q_pose, with_clearance=True)
        min_distance = self.min_distance(q)
        if self._reaches(q, pose) and min_distance >= self.clearance_m - CLEARANCE_SLACK_M:
            return IKResult(True, q, "", min_distance)
        reason, blocking = self._collision_reason(pose, q_pose, q, min_distance)
        return IKResult(False, q, reason, min_distance, blocking)

    def _collision_reason(self, pose: np.ndarray, q_pose: np.ndarray, q: np.ndarray,
                          min_distance: float) -> tuple[str, tuple[ClosePair, ...]]:
        """Why the clearance-keeping answer ``q`` failed, naming what blocks the pose.

        Args:
            pose: (3,) the target planar pose.
            q_pose: (7,) stage (1)'s answer: reaches the pose, closer than the clearance.
            q: (7,) stage (2)'s answer (clearance constrained), with ``min_distance`` (m).
        """
        clearance = self.clearance_m
        reached = self._reaches(q, pose)
        if reached:  # the pose, but short of the clearance: what is too close at q
            blocking = self.close_pairs(q, clearance - CLEARANCE_SLACK_M)
        else:  # the clearance, but not the pose: what is in the way at the pose
            blocking = self.close_pairs(q_pose, clearance)
        if not blocking:  # only pairs without a robot geometry (not expected)
            return (f"collision: geometry {format_mm(min_distance, clearance)} mm apart, inside "
                    f"the {format_mm(clearance, min_distance)} mm clearance"), ()
        first = blocking[0]
        reason = (f"collision: at the pose, {first.describe(clearance)}, inside the "
                  f"{format_mm(clearance, first.distance_m)} mm clearance")
        others = list(dict.fromkeys(f"{p.other_kind} '{p.other}'" for p in blocking[1:]
                                    if (p.other_kind, p.other) != (first.other_kind,
                                                                   first.other)))
        if others:
            reason += f" (also inside it: {', '.join(others)})"
        if reached:
            return reason + "; no solution found keeps the clearance there", blocking
        position_error, heading_error = self._pose_error(q, pose)
        misses = []
        if (position_error > 2 * POSITION_TOLERANCE_M
                or heading_error > 2 * ORIENTATION_TOLERANCE_RAD):
            misses.append(f"misses the pose by {position_error * 1e3:.2f} mm and "
                          f"{np.rad2deg(heading_error):.2f} deg")
        if not self._within_limits(q):
            misses.append("leaves the joint limits")
        if min_distance < 0:
            misses.append(f"still penetrates by {format_mm(-min_distance, 0.0)} mm")
        elif min_distance < clearance - CLEARANCE_SLACK_M:
            misses.append(f"keeps only {format_mm(min_distance, clearance)} mm")
        return reason + "; the best clearance-keeping solution " + " and ".join(misses), blocking

    def _within_limits(self, q_arm: np.ndarray) -> bool:
        return not (np.any(q_arm < self.lower - 1e-9) or np.any(q_arm > self.upper + 1e-9))

    def _pose_error(self, q_arm: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
        """Palm position error (m) and heading error (rad) of ``q_arm`` from ``pose``."""
        x, y, theta, z = self.palm_pose(q_arm)
        position_error = np.linalg.norm([x - pose[0], y - pose[1], z - self.world.palm_height_m])
        return float(position_error), abs(float(wrap_angle(theta - pose[2])))

    def _reaches(self, q_arm: np.ndarray, pose: np.ndarray) -> bool:
        """Does ``q_arm`` lie within the joint limits and put the palm at ``pose``?"""
        if not self._within_limits(q_arm):
            return False
        position_error, heading_error = self._pose_error(q_arm, pose)
        return (position_error <= 2 * POSITION_TOLERANCE_M
                and heading_error <= 2 * ORIENTATION_TOLERANCE_RAD)

    def solve_multistart(
        self, pose: np.ndarray, *, rng: np.random.Generator, attempts: int = 30
    ) -> IKResult:
        """Solve from HERB's home and from random seeds; return the feasible solution
        closest to home (used once per episode, for the first pose).

        When no seed succeeds, the last collision failure is returned if any seed reached
        the pose (a blocked pose is not unreachable), else the last failure.
        """
        best: IKResult | None = None
        last = collision = None
        for k in range(attempts):
            seed = self.home if k == 0 else rng.uniform(self.lower, self.upper)
            result = self.solve(pose, seed)
            last = result
            if not result.feasible and result.reason.startswith("collision"):
                collision = result
            if result.feasible and (best is None or np.sum((result.q - self.home) ** 2)
                                    < np.sum((best.q - self.home) ** 2)):
                best = result
            if best is not None and k >= 4:
                break
        return best if best is not None else (collision or last)

    def min_distance(self, q_arm: np.ndarray, influence_m: float = 0.1) -> float:
        """Smallest signed distance (m) among unfiltered geometry pairs at ``q_arm``."""
        self.plant.SetPositions(self._plant_context, self.full_positions(q_arm))
        query = self.plant.get_geometry_query_input_port().Eval(self._plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints(influence_m)
        return min((p.distance for p in pairs), default=influence_m)

    def close_pairs(self, q_arm: np.ndarray, within_m: float) -> tuple[ClosePair, ...]:
        """The unfiltered pairs of a robot geometry and any other geometry closer than
        ``within_m`` (m) at ``q_arm`` (7,), closest (deepest) first, from Drake's
        signed-distance query."""
        self.plant.SetPositions(self._plant_context, self.full_positions(q_arm))
        query = self.plant.get_geometry_query_input_port().Eval(self._plant_context)
        inspector = query.inspector()
        robot = {self.world.wam, self.world.hand.instance}
        obstacles = {o.spec.name for o in self.world.scene.obstacles}

        def side(geometry_id):
            body = self.plant.GetBodyFromFrameId(inspector.GetFrameId(geometry_id))
            return (body.model_instance() in robot, body.name(),
                    inspector.GetName(geometry_id).split("::")[-1])

        pairs = []
        for p in query.ComputeSignedDistancePairwiseClosestPoints(within_m):
            if not p.distance < within_m:
                continue
            a, b = side(p.id_A), side(p.id_B)
            if not a[0]:
                a, b = b, a
            if not a[0]:
                continue  # two environment geometries: not the robot's clearance
            kind = ("robot link" if b[0] else "obstacle" if b[1] in obstacles
                    else "environment body")
            pairs.append(ClosePair(float(p.distance), a[1], a[2], b[1], b[2], kind))
        return tuple(sorted(pairs, key=lambda pair: pair.distance_m))

    def _solve_once(self, pose, seed, *, with_clearance: bool):
        plant = self.plant
        ik = InverseKinematics(plant, self._plant_context, with_joint_limits=True)
        q = ik.q()
        X = self.world.X_W_palm(pose)
        p = X.translation()
        ik.AddPositionConstraint(self.world.hand.palm_frame, np.zeros(3), plant.world_frame(),
                                 p - POSITION_TOLERANCE_M, p + POSITION_TOLERANCE_M)
        ik.AddOrientationConstraint(self.world.hand.palm_frame, RotationMatrix(),
                                    plant.world_frame(), X.rotation(), ORIENTATION_TOLERANCE_RAD)
        if with_clearance:
            ik.AddMinimumDistanceLowerBoundConstraint(self.clearance_m)
        prog = ik.prog()
        arm = q[self._arm_slice]
        hand_indices = [i for i in range(plant.num_positions())
                        if not self._arm_slice.start <= i < self._arm_slice.stop]
        for i in hand_indices:
            prog.AddBoundingBoxConstraint(self._q_full[i], self._q_full[i], q[i])
        prog.AddQuadraticErrorCost(np.eye(NUM_ARM_JOINTS), seed, arm)
        if self.posture_weight > 0:
            prog.AddQuadraticErrorCost(self.posture_weight * np.eye(NUM_ARM_JOINTS), self.home,
                                       arm)
        prog.SetInitialGuess(q, self.full_positions(seed))
        result = Solve(prog)
        return result.is_success(), result.GetSolution(q)[self._arm_slice]


@dataclass(frozen=True)
class JointPath:
    """Arm configurations along a sequence of planar hand poses.

    Attributes:
        poses: (N, 3) planar palm poses (m, m, rad) actually solved (up to a failure).
        q: (N, 7) arm joint angles (rad), one row per pose.
        feasible: whether every requested pose was solved.
        reason: why the first infeasible pose failed ('' when feasible).
    """

    poses: np.ndarray
    q: np.ndarray
    feasible: bool
    reason: str = ""


def straight_push_path(
    ik: PlanarHandIK,
    start_pose: np.ndarray,
    distance_m: float,
    q_start: np.ndarray,
    *,
    step_m: float = 0.01,
) -> JointPath:
    """Solve IK every ``step_m`` along a straight push of ``distance_m`` in direction theta.

    Each pose is warm-started from the previous solution. Stops at the first infeasible
    pose and reports it (``feasible=False``) with the path up to it.
    """
    start_pose = np.asarray(start_pose, dtype=float)
    count = max(1, int(np.ceil(distance_m / step_m - 1e-9)))
    heading = np.array([np.cos(start_pose[2]), np.sin(start_pose[2]), 0.0])
    steps = np.minimum(np.arange(1, count + 1) * step_m, distance_m)
    return solve_chain(ik, start_pose, q_start, start_pose + steps[:, None] * heading)


def solve_chain(ik: PlanarHandIK, start_pose: np.ndarray, q_start: np.ndarray,
                targets: np.ndarray) -> JointPath:
    """Solve IK at each of ``targets`` (N, 3) in turn, each warm-started from the previous
    solution (the first from ``q_start`` (7,) at ``start_pose`` (3,)).

    Returns:
        The path from the start through the solved targets; at the first infeasible target
        it stops, with ``feasible=False`` and the reason (which target, where, why).
    """
    poses, qs = [np.asarray(start_pose, dtype=float)], [np.asarray(q_start, dtype=float)]
    for k, pose in enumerate(np.asarray(targets, dtype=float), start=1):
        result = ik.solve(pose, qs[-1])
        if not result.feasible:
            return JointPath(np.array(poses), np.array(qs), False,
                             f"pose {k} of {len(targets)} ({pose[0]:.3f}, {pose[1]:.3f}) m: "
                             f"{result.reason}")
        poses.append(pose)
        qs.append(result.q)
    return JointPath(np.array(poses), np.array(qs), True)


def time_parameterize(
    q: np.ndarray,
    poses: np.ndarray,
    *,
    hand_speed_m_per_s: float,
    velocity_limits: np.ndarray,
    limit_fraction: float = 0.8,
) -> np.ndarray:
    """Knot times (s), shape (N,), for a joint path moved at a nominal hand speed.

    Each segment takes the time the hand needs at ``hand_speed_m_per_s`` or, if longer,
    the time that keeps every joint within ``limit_fraction`` of its velocity limit.
    """
    hand_step = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1) / hand_speed_m_per_s
    joint_step = np.max(np.abs(np.diff(q, axis=0)) / (limit_fraction * velocity_limits), axis=1)
    return np.concatenate([[0.0], np.cumsum(np.maximum(hand_step, joint_step))])
