"""Drawing the configuration lattice in Meshcat, live and into the recording (thesis
Fig. 7.1): the palm positions of the edges the planner has evaluated so far, feasible in
green and infeasible in red, and the motion being executed as a thick blue segment.

Each check draws the edges evaluated since the last as one new line-segment object, made
visible from that time on (Meshcat animates visibility, not geometry), so the replay shows
the lattice growing with the search; likewise each commanded motion is one segment, visible
until the next. What has been drawn is Meshcat's state, so the drawer keeps its count of
it as members (like Drake's own Meshcat visualizers), not in the Context.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import EventStatus, LeafSystem

from diagrams.herb.executor import EXECUTOR_STATE_SIZE
from planning.lattice.lattice import ConfigurationLattice

FEASIBLE_RGBA = Rgba(0.1, 0.65, 0.2, 0.9)
INFEASIBLE_RGBA = Rgba(0.85, 0.1, 0.1, 0.9)
CHOSEN_RGBA = Rgba(0.1, 0.3, 0.95, 1.0)


class LatticeDrawer(LeafSystem):
    """Input port: ``executor_state`` (the executor's: the commanded palm pose first).

    Args:
        meshcat: where to draw.
        lattice: the scene's lattice (read, never evaluated, by the drawer).
        height_m: drawing height (m): just above the table top.
        period_s: drawing period (s).
    """

    def __init__(self, meshcat: Meshcat, lattice: ConfigurationLattice, *, height_m: float,
                 period_s: float = 0.1):
        super().__init__()
        self._meshcat = meshcat
        self._lattice = lattice
        self._height = height_m
        self._drawn = 0
        self._batches = 0
        self._pose: np.ndarray | None = None
        self._motions = 0
        self._executor = self.DeclareVectorInputPort("executor_state", EXECUTOR_STATE_SIZE)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._draw)
        self.DeclareForcedPublishEvent(self._draw)

    def _segment_ends(self, edges) -> tuple[np.ndarray, np.ndarray]:
        """(3, N) start and end points of the edges' palm motions."""
        poses = self._lattice.poses
        starts = np.array([poses[e.point, :2] for e in edges])
        ends = np.array([poses[e.target, :2] for e in edges])
        z = np.full((1, len(edges)), self._height)
        return np.vstack([starts.T, z]), np.vstack([ends.T, z])

    def _draw(self, context) -> EventStatus:
        t, meshcat = context.get_time(), self._meshcat
        edges = [e for e in self._lattice.evaluated_edges()[self._drawn:] if e.target >= 0]
        self._drawn = len(self._lattice.evaluated_edges())
        for ok, rgba in ((True, FEASIBLE_RGBA), (False, INFEASIBLE_RGBA)):
            chosen = [e for e in edges if e.feasible == ok]
            if not chosen:
                continue
            path = f"/lattice/{'feasible' if ok else 'infeasible'}/{self._batches}"
            start, end = self._segment_ends(chosen)
            meshcat.SetLineSegments(path, start, end, 2.0, rgba)
            meshcat.SetProperty(path, "visible", False, 0.0)
            meshcat.SetProperty(path, "visible", True, t)
            self._batches += 1
        pose = self._executor.Eval(context)[:3]
        if self._pose is None:
            self._pose = pose.copy()
        elif np.linalg.norm(pose[:2] - self._pose[:2]) > 1e-6:  # a new motion was commanded
            z = self._height + 0.002
            path = f"/lattice/chosen/{self._motions}"
            meshcat.SetLineSegments(path, np.append(self._pose[:2], z)[:, None],
                                    np.append(pose[:2], z)[:, None], 6.0, CHOSEN_RGBA)
            meshcat.SetProperty(path, "visible", False, 0.0)
            meshcat.SetProperty(path, "visible", True, t)
            if self._motions:
                meshcat.SetProperty(f"/lattice/chosen/{self._motions - 1}", "visible", False, t)
            self._motions += 1
            self._pose = pose.copy()
        return EventStatus.Succeeded()
