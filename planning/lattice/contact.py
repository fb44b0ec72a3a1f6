"""Un-modelled contact of the movable object (thesis sec. 7.1.2): the object touching an
obstacle, or leaving the table.

The hand-relative pushing model knows only the hand; an object that touches anything else
moves in a way it does not model, and Lat-POMDP sends the state to ``s_bad``. The check is
planar, like the pushing model: the object's footprint at its world pose
(``X_W_object = X_W_hand(x_r) * X_HO``) against each obstacle's footprint, by the exact
signed distance of convex polygons (:func:`models.planar.polygon.signed_distances`, batched
over poses; cylinders are 32-gons there), and its centre against the table top.

Not checked: the object touching an arm link other than the hand. At the ch. 7 palm height
(6 cm above the table) the forearm and wrist pass above the bottle; a scene with a taller
object or a lower palm would need the arm's footprint here.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from models.herb.scene import SceneSpec
from models.planar.polygon import ConvexPolygons, pose_points, signed_distances
from models.se2 import compose

#: Signed distance (m) below which the object counts as touching an obstacle.
CONTACT_DISTANCE_M = 0.0
#: How many poses per pose asked :meth:`UnmodelledContact.free_starts` draws before it
#: gives up.
MAX_START_DRAWS = 1000


class UnmodelledContact:
    """Which object poses touch an obstacle or leave the table, in one scene.

    Args:
        scene: the scene (its obstacles and table; its object's footprint).
    """

    def __init__(self, scene: SceneSpec):
        self.scene = scene
        footprints = [pose_points(o.pose.as_array()[None], o.spec.footprint())[0]
                      for o in scene.obstacles]
        self._obstacles = ConvexPolygons.from_list(footprints) if footprints else None
        self._object = ConvexPolygons.from_list([scene.object.footprint()])

    def touches(self, hand_poses: np.ndarray, object_poses: np.ndarray) -> np.ndarray:
        """(K,) bool: does the object at hand-frame pose ``object_poses`` (K, 3), with the
        palm at world pose ``hand_poses`` (K, 3) (m, m, rad), touch an obstacle or leave
        the table? NaN object poses (outside the planning region) touch nothing."""
        world = compose(hand_poses, object_poses)
        known = ~np.isnan(world[:, 0])
        out = np.zeros(len(world), dtype=bool)
        if not known.any():
            return out
        poses = world[known]
        table = self.scene.table
        off = ((np.abs(poses[:, 0] - table.center_xy_m[0]) > table.size_m[0] / 2)
               | (np.abs(poses[:, 1] - table.center_xy_m[1]) > table.size_m[1] / 2))
        hit = off
        if self._obstacles is not None:
            distances = signed_distances(self._obstacles, self._object, poses)
            hit = hit | (distances.min(axis=1) < CONTACT_DISTANCE_M)
        out[known] = hit
        return out

    def free_start(self, draw: Callable[[int], np.ndarray], *, batch: int = 1) -> np.ndarray:
        """(3,) the first of the hand-frame object poses that ``draw(batch) -> (batch, 3)``
        returns which touches nothing with the palm at the scene's start: an object does
        not start inside the clutter (placed there, the physics throws it out, often
        toppled). Poses are drawn ``batch`` at a time, so a caller keeps the random
        numbers it consumed before (the closed-loop episodes draw 1, the Lat-POMDP
        study 64).

        Raises:
            ValueError: no free pose in :data:`MAX_START_DRAWS` draws.
        """
        return self.free_starts(draw, 1, batch=batch)[0]

    def free_starts(self, draw: Callable[[int], np.ndarray], n: int, *,
                    batch: int) -> np.ndarray:
        """(n, 3) the first ``n`` poses of ``draw(batch) -> (batch, 3)``, drawn ``batch`` at
        a time, that touch nothing with the palm at the scene's start (see
        :meth:`free_start`; a particle belief conditioned the same way draws n at a time).

        Raises:
            ValueError: fewer than ``n`` free poses in ``n`` x :data:`MAX_START_DRAWS` draws.
        """
        palm = np.tile(self.scene.hand_start.as_array(), (batch, 1))
        kept, found = [], 0
        for _ in range(0, n * MAX_START_DRAWS, batch):
            poses = draw(batch)
            kept.append(poses[~self.touches(palm, poses)])
            found += len(kept[-1])
            if found >= n:
                return np.concatenate(kept)[:n]
        raise ValueError(f"no pose free of the clutter of scene {self.scene.name!r} in "
                         f"{n * MAX_START_DRAWS} draws from the belief"
                         + ("" if n == 1 else f" (found {found} of {n})"))
