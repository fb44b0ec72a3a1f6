"""The planar BarrettHand: the 3-D Drake hand projected onto the push plane, with binary
contact sensors on its front.

One source of truth: the hand is built in a ``MultibodyPlant`` by :mod:`models.herb.hand` from
``barrett_hand.yaml``, posed in its push preshape, and every collision geometry (boxes and
cylinders) is projected along the palm's x axis (vertical when pushing, see
:func:`models.herb.mount.X_W_palm`) onto the plane of the palm's (z, y) axes, which become the
planar hand frame's (x, y). Each projection is a convex polygon, so the planar hand is a
union of convex polygons.

Why a projection is the right slice: an object is a vertical prism taller than the hand's
vertical extent (the box is 12 cm tall, the hand spans 8.9 cm about the palm centre), so
the 3-D distance between the hand and the object equals the 2-D distance between the
hand's footprint and the object's outline (``tests/models/planar/test_hand_vs_drake.py``).

Sensors: with the push preshape (fingers open, distal links bent 42 deg inwards) the
surfaces an object can touch are the fingertips and the distal links' outer faces; the
inner faces look into a 2 cm-wide cage no pushed object enters. Sensors are therefore laid
along the hand's *front contour* (the part of the outline seen from straight ahead, facing
forward), split into ``front_sensors`` pieces of equal length, as the thesis' "contact
sensors distributed uniformly across the front surface of the hand" (sec. 4.3.1). The
count comes from a layout file, ``models/assets/planar_sensors/<name>.yaml``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import shapely
from pydrake.geometry import Box, Cylinder, Role, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant
from scipy.spatial import ConvexHull

from models.config import Fields, resolve_asset
from models.herb.hand import BarrettHandSpec, add_barrett_hand
from models.herb.tactile import TactileLayout
from models.planar.polygon import ConvexPolygons

CYLINDER_PROJECTION_SEGMENTS = 48
LAYOUT_KINDS = ("front", "links")
LINKS = ("palm", "f12_proximal", "f12_distal", "f3_proximal", "f3_distal")
FRONT_SAMPLE_SPACING_M = 0.5e-3


@dataclass(frozen=True)
class PlanarSensorLayout:
    """Binary contact sensors on the planar hand's front contour.

    Two kinds (``kind``):

    - ``front``: the front contour split into ``front_sensors`` equal-length sensors (the
      MPF experiments' "sensors distributed uniformly across the front surface", and with
      two, one per fingertip, the planning experiments' fingertip sensors);
    - ``links``: every link is one sensor over all of its outline an object can reach
      (thesis sec. 6.4.4, "each of the hand's seven links served as a binary contact
      sensor"). F1 and F2 project onto the same polygons, so the planar hand has five:
      palm (with the knuckles and the F/T sensor), F1/F2 proximal, F1/F2 distal, F3
      proximal, F3 distal.

    Attributes:
        name: layout name (file stem).
        front_sensors: number of equal-length sensors along the front contour (``front``).
        min_facing: an outline edge belongs to the front if its outward normal's x
            component exceeds this (0 = any forward-facing edge).
        probe_radius_m: radius (m) of the smallest object considered: outline pockets such
            a disk cannot reach from outside are not front (no pushed object fits through
            the 6 mm gap between the fingertips, so the palm behind it is not front).
    """

    name: str
    front_sensors: int
    min_facing: float = 0.0
    probe_radius_m: float = 0.005
    kind: str = "front"

    def __post_init__(self):
        if self.kind not in LAYOUT_KINDS:
            raise ValueError(f"kind must be one of {LAYOUT_KINDS}, got {self.kind!r}")

    @staticmethod
    def load(name_or_path: str | Path = "medium") -> PlanarSensorLayout:
        """Load ``low``, ``medium``, ``high``, ``fingertips``, ``links`` (built in) or a
        layout file by path.

        ``front_sensors`` is required for ``kind: front``. The other fields are optional by
        design, and every built-in layout relies on their defaults: ``kind`` is ``front``;
        a ``links`` layout has one sensor per link (``front_sensors``, if given, must be
        5); ``min_facing`` is 0 (every forward-facing edge is front) and
        ``probe_radius_m`` 0.005 m (the smallest pushed object: no object fits through the
        fingertips' 6 mm gap), both modelling choices of the front contour, not measured
        quantities.

        Raises:
            ConfigError: naming the file and field of a missing or malformed entry.
        """
        path = resolve_asset("planar_sensors", name_or_path)
        fields = Fields.from_file(path)
        kind = fields.string("kind", "front", choices=LAYOUT_KINDS)
        count = (fields.number("front_sensors", len(LINKS), min=1, max=60, integer=True)
                 if kind == "links" else
                 fields.number("front_sensors", min=1, max=60, integer=True))
        if kind == "links" and count != len(LINKS):
            raise fields.error("front_sensors", f"a links layout has one sensor per link "
                                                f"({len(LINKS)}), got {count}")
        layout = PlanarSensorLayout(
            name=path.stem,
            front_sensors=int(count),
            kind=kind,
            min_facing=fields.number("min_facing", 0.0, min=0.0, max=0.99),
            probe_radius_m=fields.number("probe_radius_m", 0.005, min=0.0, max=0.05),
        )
        fields.done()
        return layout


@dataclass(frozen=True)
class PlanarHand:
    """The hand in the planar hand frame H (m).

    Attributes:
        parts: the hand as P convex polygons.
        part_names: (P,) name of the Drake geometry each part projects.
        sensor_segments: (S, 2, 2) line segments (start, end) of the sensors.
        sensor_of_segment: (S,) sensor index of each segment.
        sensor_count: number of sensors.
        layout: the sensor layout.
    """

    parts: ConvexPolygons
    part_names: tuple[str, ...]
    sensor_segments: np.ndarray
    sensor_of_segment: np.ndarray
    sensor_count: int
    layout: PlanarSensorLayout

    @property
    def outline(self) -> shapely.Geometry:
        """The union of the parts (a Shapely polygon)."""
        return _union(self.parts)

    @property
    def sensor_polygons(self) -> ConvexPolygons:
        """The sensor segments as two-vertex polygons (for the batched queries)."""
        return ConvexPolygons.from_list(list(self.sensor_segments))

    @staticmethod
    def load(layout: str | Path | PlanarSensorLayout = "medium",
             hand_file: str | Path | None = None) -> PlanarHand:
        """The planar hand of ``barrett_hand.yaml`` (or ``hand_file``) with sensor ``layout``."""
        if not isinstance(layout, PlanarSensorLayout):
            layout = PlanarSensorLayout.load(layout)
        parts, names = _merge_convex(*_projected_parts(str(hand_file) if hand_file else ""))
        polygons = ConvexPolygons.from_list(list(parts))
        if layout.kind == "links":
            segments, owner = link_sensors(polygons, names, layout)
            count = len(LINKS)
        else:
            segments, owner = front_sensors(polygons, layout)
            count = layout.front_sensors
        return PlanarHand(polygons, names, segments, owner, count, layout)


@lru_cache(maxsize=4)
def _projected_parts(hand_file: str) -> tuple[tuple[np.ndarray, ...], tuple[str, ...]]:
    """Project every collision geometry of the preshaped Drake hand onto the push plane."""
    spec = BarrettHandSpec.load(hand_file or None)
    # A bare plant and SceneGraph (no Diagram): body poses come from the plant's own
    # context and geometry poses in their bodies from the inspector.
    plant = MultibodyPlant(1e-3)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kLagged)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    hand = add_barrett_hand(plant, spec, TactileLayout())
    plant.WeldFrames(plant.world_frame(), hand.base.body_frame(), RigidTransform())
    plant.Finalize()
    plant_context = plant.CreateDefaultContext()
    spread, proximal = hand.preshape[0], hand.preshape[1]
    for joint_name, value in [("bh_f1_spread", spread), ("bh_f2_spread", spread)] + [
        (f"bh_{f}_{link}", proximal * (spec.distal_coupling if link == "distal" else 1.0))
        for f in ("f1", "f2", "f3") for link in ("proximal", "distal")
    ]:
        plant.GetJointByName(joint_name, hand.instance).set_angle(plant_context, value)
    inspector = scene_graph.model_inspector()
    X_PW = spec.X_BaseP.inverse()
    polygons, names = [], []
    for gid in inspector.GetAllGeometryIds(Role.kProximity):
        corners = _shape_points(inspector.GetShape(gid))
        body = plant.GetBodyFromFrameId(inspector.GetFrameId(gid))
        X_WG = plant.EvalBodyPoseInWorld(plant_context, body) @ inspector.GetPoseInFrame(gid)
        p_P = (X_PW @ X_WG).multiply(corners.T).T
        planar = p_P[:, [2, 1]]  # palm z -> planar x (forward), palm y -> planar y
        polygon = planar[ConvexHull(planar).vertices]  # 2-D hulls come counter-clockwise
        name = inspector.GetName(gid).split("::")[-1]
        twin = next((i for i, q in enumerate(polygons)
                     if q.shape == polygon.shape and np.allclose(q, polygon, atol=1e-9)), None)
        if twin is None:  # F1 and F2 project onto the same polygons: keep one
            polygons.append(polygon)
            names.append(name)
        else:
            names[twin] += "+" + name
    return tuple(polygons), tuple(names)


def _merge_convex(polygons: tuple[np.ndarray, ...],
                  names: tuple[str, ...]) -> tuple[list[np.ndarray], tuple[str, ...]]:
    """Greedily merge parts whose union is itself convex (a link's sensing and non-sensing
    halves, the palm body and its pads): fewer parts, same outline, faster queries."""
    polys = [shapely.Polygon(p) for p in polygons]
    names = list(names)
    merged = True
    while merged:
        merged = False
        for i in range(len(polys)):
            for j in range(i + 1, len(polys)):
                union = shapely.union(polys[i].buffer(1e-7, join_style="mitre"),
                                      polys[j].buffer(1e-7, join_style="mitre"))
                hull = union.convex_hull
                if union.geom_type == "Polygon" and hull.area - union.area < 1e-9:
                    polys[i] = hull
                    names[i] += "+" + names.pop(j)
                    polys.pop(j)
                    merged = True
                    break
            if merged:
                break
    out = []
    for poly in polys:
        ring = shapely.LinearRing(shapely.simplify(poly, 1e-9).exterior.coords)
        coords = np.asarray((ring if ring.is_ccw else ring.reverse()).coords)[:-1]
        out.append(coords)
    return out, tuple(names)


def _shape_points(shape) -> np.ndarray:
    """Points (N, 3) whose convex hull is the shape, in the geometry frame (m)."""
    if isinstance(shape, Box):
        half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        return signs * half
    if isinstance(shape, Cylinder):
        a = 2 * np.pi * np.arange(CYLINDER_PROJECTION_SEGMENTS) / CYLINDER_PROJECTION_SEGMENTS
        ring = np.column_stack([shape.radius() * np.cos(a), shape.radius() * np.sin(a)])
        half = shape.length() / 2
        return np.vstack([np.column_stack([ring, np.full(len(a), z)]) for z in (-half, half)])
    raise TypeError(f"cannot project hand geometry of type {type(shape).__name__}")


def _valid(polygons: ConvexPolygons, i: int) -> np.ndarray:
    return polygons.vertices[i][polygons.valid[i]]


def _union(parts: ConvexPolygons) -> shapely.Geometry:
    """Union of the parts; each grown by 1 um so that parts that touch merge exactly."""
    grown = [shapely.Polygon(_valid(parts, i)).buffer(1e-6, join_style="mitre")
             for i in range(len(parts))]
    return shapely.union_all(grown)


def link_of_part(name: str) -> int:
    """Index into ``LINKS`` of a merged part (names of the Drake geometries it holds)."""
    first = name.split("+")[0]
    finger = "f3" if first.startswith("f3") else "f12"
    if "distal" in first or first.endswith("_tip"):
        return LINKS.index(f"{finger}_distal")
    if "proximal" in first:
        return LINKS.index(f"{finger}_proximal")
    return LINKS.index("palm")


def _outline_edges(outline: shapely.Geometry, probe_radius_m: float):
    """The outline's edges (at most FRONT_SAMPLE_SPACING_M long), counter-clockwise from the
    rearmost point: (start, end, outward normal, length, reachable by the probe disk)."""
    ring = shapely.segmentize(shapely.LinearRing(outline.exterior.coords),
                              FRONT_SAMPLE_SPACING_M)
    if not ring.is_ccw:
        ring = ring.reverse()
    pts = np.asarray(ring.coords)[:-1]
    pts = np.roll(pts, -int(np.argmin(pts[:, 0])), axis=0)
    pts = np.vstack([pts, pts[:1]])
    start, end = pts[:-1], pts[1:]
    edge = end - start
    length = np.linalg.norm(edge, axis=1)
    keep = length > 1e-9
    start, end, edge, length = start[keep], end[keep], edge[keep], length[keep]
    normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / length[:, None]
    mid = (start + end) / 2 + 1e-6 * normal
    # A disk of the probe radius reaches an edge from outside when the edge lies within the
    # radius of the dilated outline's outer boundary (pockets behind narrow gaps become
    # holes of the dilation and are excluded).
    r = max(probe_radius_m, 1e-6)
    outer = shapely.Polygon(outline.buffer(r, quad_segs=32).exterior).exterior
    reachable = shapely.distance(shapely.points(mid), outer) <= r * 1.01 + 1e-6
    return start, end, normal, mid, reachable


def link_sensors(parts: ConvexPolygons, names: tuple[str, ...],
                 layout: PlanarSensorLayout) -> tuple[np.ndarray, np.ndarray]:
    """One sensor per link (``LINKS``): the reachable outline edges nearest to its parts.

    Returns:
        ``segments`` (S, 2, 2) and the sensor index (S,) of each, grouped by sensor.
    """
    outline = _union(parts)
    if outline.geom_type != "Polygon":
        raise ValueError("the planar hand is not one connected polygon")
    start, end, _, mid, reachable = _outline_edges(outline, layout.probe_radius_m)
    polygons = [shapely.Polygon(_valid(parts, i)) for i in range(len(parts))]
    nearest = np.argmin(shapely.distance(shapely.points(mid)[:, None],
                                         np.array(polygons)[None, :]), axis=1)
    link = np.array([link_of_part(n) for n in names])[nearest]
    keep = reachable
    order = np.argsort(link[keep], kind="stable")
    segments = np.stack([start[keep], end[keep]], axis=1)[order]
    return _merge_collinear(segments, link[keep][order])


def front_sensors(parts: ConvexPolygons,
                  layout: PlanarSensorLayout) -> tuple[np.ndarray, np.ndarray]:
    """Split the hand's front contour into ``layout.front_sensors`` equal-length sensors.

    The front contour is the part of the outline (union of ``parts``) whose outward normal
    points forward (x component > ``min_facing``), which is seen from straight ahead (a
    ray in +x from it leaves the hand without touching it again) and which a disk of
    ``probe_radius_m`` coming from outside can touch.

    Returns:
        ``segments`` (S, 2, 2) and the sensor index (S,) of each segment, ordered from -y
        (the F1/F2 side) to +y along the outline.
    """
    outline = _union(parts)
    if outline.geom_type != "Polygon":
        raise ValueError("the planar hand is not one connected polygon")
    start, end, normal, mid, reachable = _outline_edges(outline, layout.probe_radius_m)
    far = mid.copy()
    far[:, 0] = mid[:, 0] + 1.0
    rays = shapely.linestrings(np.stack([mid, far], axis=1))
    visible = ~shapely.intersects(rays, outline)
    front = (normal[:, 0] > layout.min_facing) & visible & reachable
    if not np.any(front):
        raise ValueError("the hand has no front contour")
    starts, ends = start[front], end[front]
    seg_len = np.linalg.norm(ends - starts, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    bounds = np.linspace(0.0, total, layout.front_sensors + 1)
    segments, owner = [], []
    for s in range(layout.front_sensors):
        lo, hi = bounds[s], bounds[s + 1]
        for j in range(len(starts)):
            a, b = max(lo, cum[j]), min(hi, cum[j + 1])
            if b - a <= 1e-12:
                continue
            d = ends[j] - starts[j]
            p0 = starts[j] + d * (a - cum[j]) / seg_len[j]
            p1 = starts[j] + d * (b - cum[j]) / seg_len[j]
            segments.append(np.stack([p0, p1]))
            owner.append(s)
    return _merge_collinear(np.array(segments), np.array(owner))


def _merge_collinear(segments: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Join consecutive segments of one sensor that continue each other in a straight line."""
    out, out_owner = [segments[0].copy()], [owner[0]]
    for seg, s in zip(segments[1:], owner[1:], strict=True):
        last = out[-1]
        d0, d1 = last[1] - last[0], seg[1] - seg[0]
        cross = d0[0] * d1[1] - d0[1] * d1[0]
        joined = np.allclose(last[1], seg[0], atol=1e-9)
        if s == out_owner[-1] and joined and abs(cross) < 1e-12 * max(1.0, d0 @ d1) and (
                d0 @ d1 > 0):
            last[1] = seg[1]
        else:
            out.append(seg.copy())
            out_owner.append(s)
    return np.array(out), np.array(out_owner)
