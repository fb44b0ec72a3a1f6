"""Batched forward kinematics of an arm's ball centres and their translational Jacobians,
extracted once from the Drake plant.

Drake evaluates one context at a time (set positions, then ask a frame's pose or a
point's Jacobian), about 10-50 microseconds per call from Python; the constraint
projection asks for every ball of every particle at every iteration. :class:`BallChain`
reads the chain's fixed transforms and joint axes from the plant and evaluates all K
configurations at once in compiled loops (Numba):
``X_WB_k = X_WB_{k-1} X_PF_k Rot(axis_k, q_k) X_MC_k`` and, for a point p on link m, the
Jacobian columns ``z_j x (p - o_j)`` for joints j <= m
(the revolute joint's axis z_j and origin o_j in the world). Tests check both against
Drake's ``CalcPointsPositions`` and ``CalcJacobianTranslationalVelocity`` to 1e-9.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint

from models.arms.spec import Ball


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
        self._X_base = np.ascontiguousarray(self.X_W_base, dtype=float)
        self._X_PF = np.ascontiguousarray(np.array(self.X_PF), dtype=float)
        self._X_MC = np.ascontiguousarray(np.array(self.X_MC), dtype=float)
        self._axes = np.ascontiguousarray(np.array(self.axes), dtype=float)

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Link poses and joint axes for configurations q (K, dof) rad.

        Returns:
            (R_WB (K, dof, 3, 3), p_WB (K, dof, 3)) of each chain link's body frame, and
            (z_W (K, dof, 3), o_W (K, dof, 3)): each joint's unit axis and origin (m).
        """
        return _frames(np.ascontiguousarray(np.atleast_2d(q), dtype=float), self._X_base,
                       self._X_PF, self._X_MC, self._axes)

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
        c, J = _centres(R, p, z, o, np.ascontiguousarray(link),
                        np.ascontiguousarray(local, dtype=float), jacobian)
        return c, (J if jacobian else None)


@njit(cache=True)
def _mul33(A, B, out):
    """out = A B for 3x3 matrices (explicit loops: BLAS calls cost more at this size)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True)
def _mul3(A, v, out):
    """out = A v for a 3x3 matrix and a 3-vector."""
    for i in range(3):
        out[i] = A[i, 0] * v[0] + A[i, 1] * v[1] + A[i, 2] * v[2]


@njit(cache=True)
def _frames(q, X_base, X_PF, X_MC, axes):
    """Compiled forward kinematics of the chain for K configurations (see ``frames``)."""
    K, n = q.shape
    R = np.empty((K, n, 3, 3))
    p = np.empty((K, n, 3))
    z = np.empty((K, n, 3))
    o = np.empty((K, n, 3))
    rot, R_F, R_M, Rc = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    pc, v = np.empty(3), np.empty(3)
    for k in range(K):
        Rc[:] = X_base[:3, :3]
        pc[:] = X_base[:3, 3]
        for j in range(n):
            _mul33(Rc, X_PF[j, :3, :3], R_F)
            _mul3(Rc, X_PF[j, :3, 3], v)
            for i in range(3):
                o[k, j, i] = pc[i] + v[i]
            _mul3(R_F, axes[j], z[k, j])
            x, y, w = axes[j, 0], axes[j, 1], axes[j, 2]
            s, c = np.sin(q[k, j]), np.cos(q[k, j])
            t = 1.0 - c  # Rodrigues: I + s [a]x + (1 - c) [a]x^2, for a unit axis a
            rot[0, 0], rot[0, 1], rot[0, 2] = c + t * x * x, t * x * y - s * w, t * x * w + s * y
            rot[1, 0], rot[1, 1], rot[1, 2] = t * x * y + s * w, c + t * y * y, t * y * w - s * x
            rot[2, 0], rot[2, 1], rot[2, 2] = t * x * w - s * y, t * y * w + s * x, c + t * w * w
            _mul33(R_F, rot, R_M)
            _mul33(R_M, X_MC[j, :3, :3], Rc)
            _mul3(R_M, X_MC[j, :3, 3], v)
            for i in range(3):
                pc[i] = o[k, j, i] + v[i]
            R[k, j] = Rc
            p[k, j] = pc
    return R, p, z, o


@njit(cache=True)
def _centres(R, p, z, o, link, local, jacobian):
    """Ball centres (K, B, 3) and, when ``jacobian``, their Jacobians (K, B, 3, n): for a
    ball on link m, column j <= m is ``z_j x (c - o_j)`` (a revolute joint's velocity)."""
    K, n = R.shape[0], R.shape[1]
    B = link.shape[0]
    c = np.empty((K, B, 3))
    J = np.zeros((K, B, 3, n)) if jacobian else np.zeros((1, 1, 3, n))
    for k in range(K):
        for b in range(B):
            m = link[b]
            for i in range(3):
                c[k, b, i] = p[k, m, i] + (R[k, m, i, 0] * local[b, 0]
                                           + R[k, m, i, 1] * local[b, 1]
                                           + R[k, m, i, 2] * local[b, 2])
            if jacobian:
                for j in range(m + 1):
                    dx = c[k, b, 0] - o[k, j, 0]
                    dy = c[k, b, 1] - o[k, j, 1]
                    dz = c[k, b, 2] - o[k, j, 2]
                    J[k, b, 0, j] = z[k, j, 1] * dz - z[k, j, 2] * dy
                    J[k, b, 1, j] = z[k, j, 2] * dx - z[k, j, 0] * dz
                    J[k, b, 2, j] = z[k, j, 0] * dy - z[k, j, 1] * dx
    return c, J
