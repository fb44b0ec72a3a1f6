"""The closed loop's motion planner over the lattice: an action's joint path is the lattice
edge's own, so what the arm does is what the planner checked (thesis sec. 7.1.1: an action
instantiates its template at the robot's lattice point).

It answers the same ``plan(pose_W, q, action_H) -> JointPath`` as the IK motion planner of
:mod:`models.herb.motion`, so the closed loop's controller and executor take either.
"""

from __future__ import annotations

import numpy as np

from models.herb.kinematics import JointPath
from planning.lattice.lattice import ConfigurationLattice
from planning.lattice.planners import lattice_point

#: How far (rad) the arm may be from its lattice point's configuration.
ON_CONFIGURATION_RAD = 1e-3


class LatticeMotion:
    """Joint paths of actions from the lattice (see the module docstring).

    Attributes:
        lattice: the scene's lattice.
        ik: its kinematic model (the executor reads the joints' velocity limits there).
    """

    def __init__(self, lattice: ConfigurationLattice):
        self.lattice = lattice
        self.ik = lattice.kinematics

    def plan(self, pose_W: np.ndarray, q: np.ndarray, action_H: np.ndarray) -> JointPath:
        """The edge of the template ``action_H`` (3,) (hand frame, m, m, rad) from the
        lattice point at ``pose_W`` (3,) with the arm at ``q`` (7,) (rad); infeasible, with
        the reason, when the palm or the arm is off the lattice or the action is not one
        of its templates."""
        pose_W, q = np.asarray(pose_W, dtype=float), np.asarray(q, dtype=float)
        stay = JointPath(pose_W[None], q[None], False)
        try:
            point = lattice_point(self.lattice, palm_pose=pose_W)
        except ValueError as err:
            return JointPath(stay.poses, stay.q, False, str(err))
        match = np.flatnonzero(np.all(np.isclose(self.lattice.action_vectors,
                                                 np.asarray(action_H), atol=1e-9), axis=1))
        if not len(match):
            return JointPath(stay.poses, stay.q, False, f"{np.round(action_H, 4).tolist()} "
                                                         "is not one of the lattice's templates")
        expected = self.lattice.table.q[point]
        if not np.all(np.abs(q - expected) <= ON_CONFIGURATION_RAD):
            return JointPath(stay.poses, stay.q, False, "the arm is not at its lattice "
                             f"point's configuration (off by {np.abs(q - expected).max():.4f} "
                             "rad)")
        edge = self.lattice.edge(point, int(match[0]))
        if not edge.feasible:
            return JointPath(stay.poses, stay.q, False, edge.reason)
        return JointPath(edge.poses[:, :3], edge.q, True)
