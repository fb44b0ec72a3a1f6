"""Batched forward kinematics of an arm's ball centres and their translational Jacobians,
extracted once from the Drake plant.

Drake evaluates one context at a time (set positions, then ask a frame's pose or a
point's Jacobian), about 10-50 microseconds per call from Python; the constraint
projection asks for every ball of every particle at every iteration. :class:`BallChain`
reads the chain's fixed transforms and joint axes from the plant and evaluates all K
configurations at once with numpy: ``X_WB_k = X_WB_{k-1} X_PF_k Rot(axis_k, q_k) X_MC_k``
and, for a point p on link m, the Jacobian columns ``z_j x (p - o_j)`` for joints j <= m
(the revolute joint's axis z_j and origin o_j in the world). Tests check both against
Drake's ``CalcPointsPositions`` and ``CalcJacobianTranslationalVelocity`` to 1e-9.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint

from models.arms.spec import Ball


def _rodrigues(axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotations by ``angles`` (K,) rad about the unit axis (3,)."""
    x, y, z = axes
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3)[None] + s * K[None] + (1.0 - c) * (K @ K)[None]


class BallChain:
    """Ball centres (K, B, 3) and Jacobians (K, B, 3, dof) of a serial arm.

    Args:
        plant: the finalized plant; context: a context of it holding the positions of
            every joint that is not estimated (e.g. the hand's preshape).
        joints: the estimated revolute joints, base to tip, each the parent of the next.
        balls: the balls, on chain links or on bodies welded (or held fixed) below them.

    Raises:
        ValueError: joints that are not a serial chain, or a ball on a body not below the
            chain's first joint.
    """

    def __init__(self, plant: MultibodyPlant, context, joints: list[RevoluteJoint],
                 balls: tuple[Ball, ...]):
        for a, b in zip(joints, joints[1:], strict=False):
            if b.parent_body().index() != a.child_body().index():
                raise ValueError(f"joint {b.name()!r} does not follow {a.name()!r}")
        base = joints[0].parent_body()
        self.X_W_base = base.body_frame().CalcPoseInWorld(context).GetAsMatrix4()
        self.X_PF = [j.frame_on_parent().GetFixedPoseInBodyFrame().GetAsMatrix4()
                     for j in joints]
        self.X_MC = [np.linalg.inv(j.frame_on_child().GetFixedPoseInBodyFrame()
                                   .GetAsMatrix4()) for j in joints]
        self.axes = [np.array(j.revolute_axis()) for j in joints]
        chain_bodies = {j.child_body().index(): k for k, j in enumerate(joints)}
        parent_of = {plant.get_joint(i).child_body().index(): plant.get_joint(i).parent_body()
                     for i in plant.GetJointIndices()}
        link_index, local = [], []
        for ball in balls:
            body = plant.GetBodyByName(ball.link)
            owner = body
            while owner.index() not in chain_bodies:
                if owner.index() not in parent_of:
                    raise ValueError(f"ball on {ball.link!r} is not below joint "
                                     f"{joints[0].name()!r}")
                owner = parent_of[owner.index()]
            X_O_L = plant.CalcRelativeTransform(context, owner.body_frame(), body.body_frame())
            link_index.append(chain_bodies[owner.index()])
            local.append(X_O_L.multiply(np.array(ball.center_m)))
        self.link_index = np.array(link_index, dtype=int)  # (B,) chain link of each ball
        self.local = np.array(local).reshape(-1, 3)  # (B, 3) centre in that link's frame
        self.radii = np.array([b.radius_m for b in balls])
        self.dof = len(joints)

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Link poses and joint axes for configurations q (K, dof) rad.

        Returns:
            (R_WB (K, dof, 3, 3), p_WB (K, dof, 3)) of each chain link's body frame, and
            (z_W (K, dof, 3), o_W (K, dof, 3)): each joint's unit axis and origin (m).
        """
        q = np.atleast_2d(q)
        K = len(q)
        R = np.repeat(self.X_W_base[None, :3, :3], K, 0)
        p = np.repeat(self.X_W_base[None, :3, 3], K, 0)
        Rs, ps, zs, os = [], [], [], []
        for k in range(self.dof):
            R_F = R @ self.X_PF[k][:3, :3]
            p_F = p + R @ self.X_PF[k][:3, 3]
            zs.append(R_F @ self.axes[k])
            os.append(p_F)
            R_M = R_F @ _rodrigues(self.axes[k], q[:, k])
            R = R_M @ self.X_MC[k][:3, :3]
            p = p_F + R_M @ self.X_MC[k][:3, 3]
            Rs.append(R)
            ps.append(p)
        return (np.stack(Rs, 1), np.stack(ps, 1), np.stack(zs, 1), np.stack(os, 1))

    def centers(self, q: np.ndarray, *, jacobian: bool = False,
                balls: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Ball centres in the world (K, B, 3) m and, when asked, their translational
        Jacobians (K, B, 3, dof) m/rad with respect to the estimated joints.

        Args:
            q: (K, dof) configurations (rad).
            balls: indices of the balls wanted (default: all B).
        """
        link = self.link_index if balls is None else self.link_index[balls]
        local = self.local if balls is None else self.local[balls]
        R, p, z, o = self.frames(q)
        Rb, pb = R[:, link], p[:, link]  # (K, B, 3, 3), (K, B, 3)
        c = pb + np.einsum("kbij,bj->kbi", Rb, local)
        if not jacobian:
            return c, None
        J = np.cross(z[:, None, :, :], c[:, :, None, :] - o[:, None, :, :])  # (K,B,dof,3)
        J *= (np.arange(self.dof)[None, :] <= link[:, None])[None, :, :, None]
        return c, np.swapaxes(J, 2, 3)
