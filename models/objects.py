"""Movable objects and obstacles: shapes as data, built into the plant as free or welded bodies.

An object file (``models/assets/objects/<name>.yaml`` or any path) gives a shape, its
dimensions and a mass (``mass_kg``, kg; required), and optionally a display colour and
contact-material overrides (``contact``: see :meth:`ContactMaterial.from_fields
<models.contact.ContactMaterial.from_fields>`; without it an object is made of
:data:`~models.contact.OBJECT_MATERIAL`). Shapes:

- ``box``: ``size_m: [x, y]`` (m);
- ``cylinder``: ``radius_m`` (m);
- ``polygon``: ``vertices_m: [[x, y], ...]`` (m, convex, counter-clockwise); the body
  frame is placed at the polygon's area centroid;
- ``ellipse``: ``axes_m: [length_x, length_y]`` (m, full lengths) and ``segments`` (the
  number of vertices, 8-256); built as an inscribed convex polygon.

and every shape a ``height_m`` (m, along z).

Every object's body frame sits at the centre of its footprint, half its height above the
support surface, with z up; :meth:`ObjectSpec.footprint` is the planar outline (used by
the hand-relative 2-D world).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Cylinder, Shape
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, RigidBody, SpatialInertia, UnitInertia

from models.bodies import add_geometry, prism_inertia, prism_mesh
from models.config import Fields, resolve_asset
from models.contact import OBJECT_MATERIAL, ContactMaterial

SHAPES = ("box", "cylinder", "polygon", "ellipse")
CYLINDER_FOOTPRINT_SEGMENTS = 32


@dataclass(frozen=True)
class ObjectSpec:
    """A rigid object.

    Attributes:
        name: object name (also the body name in the plant).
        shape: one of ``box``, ``cylinder``, ``polygon`` (ellipses become polygons).
        height_m: extent along z (m).
        mass_kg: mass (kg).
        size_m: (x, y) footprint of a box (m); unused otherwise.
        radius_m: radius of a cylinder (m); unused otherwise.
        vertices_m: (V, 2) convex polygon about its centroid (m), for ``polygon``.
        material: contact material.
        rgba: display colour.
        source: the file this came from (for messages).
    """

    name: str
    shape: str
    height_m: float
    mass_kg: float
    size_m: tuple[float, float] = (0.0, 0.0)
    radius_m: float = 0.0
    vertices_m: tuple[tuple[float, float], ...] = ()
    material: ContactMaterial = OBJECT_MATERIAL
    rgba: tuple[float, float, float, float] = (0.85, 0.55, 0.2, 1.0)
    source: str = ""

    @staticmethod
    def load(name_or_path: str | Path) -> ObjectSpec:
        """Load a built-in object (``box``, ``bottle``, ``rect1``, ``ellip2``, ``butter``) or
        a user's object file."""
        path = resolve_asset("objects", name_or_path)
        fields = Fields.from_file(path)
        spec = ObjectSpec.from_fields(fields, default_name=path.stem)
        fields.done()
        return spec

    @staticmethod
    def from_fields(
        fields: Fields,
        *,
        default_name: str,
        default_material: ContactMaterial = OBJECT_MATERIAL,
        default_mass_kg: float | None = None,
    ) -> ObjectSpec:
        """Parse an object (or obstacle) mapping; the caller calls ``fields.done()``.

        Every dimension and, unless ``default_mass_kg`` is given, ``mass_kg`` are required.
        Two fields are optional by design: ``rgba`` (display only) and ``contact``, whose
        overrides apply on top of ``default_material`` (:data:`~models.contact.OBJECT_MATERIAL`
        for objects: 2e6 Pa, mu 0.4), the material of every built-in object without a
        ``contact`` section (``box``, ``bottle``, ``small_box``).

        Args:
            fields: the mapping.
            default_name: name when the mapping has no ``name``.
            default_material: the contact material that ``contact`` overrides.
            default_mass_kg: mass (kg) when ``mass_kg`` is absent; ``None`` (the default)
                makes ``mass_kg`` required. Only for bodies whose mass never enters the
                dynamics (the welded obstacles of :mod:`models.herb.scene`).

        Raises:
            ConfigError: naming the file and field of a missing or malformed entry.
        """
        name = fields.string("name", default_name)
        shape = fields.string("shape", choices=SHAPES)
        height = fields.number("height_m", min=1e-3, max=2.0)
        if shape == "box":
            geometry = dict(shape="box", size_m=fields.vector("size_m", 2, min=1e-3, max=3.0))
        elif shape == "cylinder":
            geometry = dict(shape="cylinder",
                            radius_m=fields.number("radius_m", min=1e-3, max=1.0))
        else:
            if shape == "ellipse":
                axes = fields.vector("axes_m", 2, min=1e-3, max=3.0)
                segments = int(fields.number("segments", min=8, max=256, integer=True))
                angles = 2 * np.pi * np.arange(segments) / segments
                vertices = np.column_stack([axes[0] / 2 * np.cos(angles),
                                            axes[1] / 2 * np.sin(angles)])
            else:
                vertices = _parse_vertices(fields, fields.raw("vertices_m"))
            geometry = dict(shape="polygon", vertices_m=_centred(vertices))
        if default_mass_kg is None:
            mass = fields.number("mass_kg", min=1e-4, max=1e3)
        else:
            mass = fields.number("mass_kg", default_mass_kg, min=1e-4, max=1e3)
        rgba = fields.vector("rgba", 4, (0.85, 0.55, 0.2, 1.0), min=0.0, max=1.0)
        material = (ContactMaterial.from_fields(fields.sub("contact"), default_material)
                    if fields.has("contact") else default_material)
        return ObjectSpec(name=name, height_m=height, mass_kg=mass, material=material,
                          rgba=tuple(rgba), source=fields.source, **geometry)

    @property
    def rotationally_symmetric(self) -> bool:
        """Does turning the object about its vertical axis leave it the same (a cylinder)?
        Its orientation is then unobservable and its error meaningless."""
        return self.shape == "cylinder"

    def footprint(self) -> np.ndarray:
        """(V, 2) counter-clockwise outline of the object in its body frame (m).

        Cylinders are approximated by a regular 32-gon inscribed in the circle.
        """
        if self.shape == "box":
            hx, hy = self.size_m[0] / 2, self.size_m[1] / 2
            return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        if self.shape == "cylinder":
            a = 2 * np.pi * np.arange(CYLINDER_FOOTPRINT_SEGMENTS) / CYLINDER_FOOTPRINT_SEGMENTS
            return self.radius_m * np.column_stack([np.cos(a), np.sin(a)])
        return np.array(self.vertices_m)

    def shape3d(self) -> Shape:
        """The Drake shape of the object, centred on its body frame."""
        if self.shape == "box":
            return Box(self.size_m[0], self.size_m[1], self.height_m)
        if self.shape == "cylinder":
            return Cylinder(self.radius_m, self.height_m)
        return prism_mesh(np.array(self.vertices_m), self.height_m, self.name)

    def spatial_inertia(self) -> SpatialInertia:
        """Mass properties of the solid, uniform-density object about its body origin."""
        if self.shape == "box":
            G = UnitInertia.SolidBox(self.size_m[0], self.size_m[1], self.height_m)
            return SpatialInertia(self.mass_kg, np.zeros(3), G)
        if self.shape == "cylinder":
            G = UnitInertia.SolidCylinder(self.radius_m, self.height_m, [0.0, 0.0, 1.0])
            return SpatialInertia(self.mass_kg, np.zeros(3), G)
        return prism_inertia(self.mass_kg, np.array(self.vertices_m), self.height_m)


def add_object(
    plant: MultibodyPlant,
    spec: ObjectSpec,
    instance: ModelInstanceIndex,
    *,
    name: str | None = None,
) -> RigidBody:
    """Add ``spec`` as a body (free unless the caller welds it) with collision and visual."""
    body = plant.AddRigidBody(name or spec.name, instance, spec.spatial_inertia())
    add_geometry(plant, body, RigidTransform(), spec.shape3d(), body.name(), spec.material,
                 spec.rgba)
    return body


def _parse_vertices(fields: Fields, raw: object) -> np.ndarray:
    try:
        vertices = np.asarray(raw, dtype=float)
    except (TypeError, ValueError) as err:
        raise fields.error("vertices_m", "expected a list of [x, y] pairs") from err
    if vertices.ndim != 2 or vertices.shape[1] != 2 or len(vertices) < 3:
        raise fields.error("vertices_m", "expected at least three [x, y] pairs")
    if not np.all(np.isfinite(vertices)):
        raise fields.error("vertices_m", "vertices must be finite numbers")
    if np.abs(vertices).max() > 3.0:
        raise fields.error("vertices_m", "vertices must lie within 3 m of the origin, as a "
                                         "box's size_m is at most 3 m")
    edges = np.roll(vertices, -1, axis=0) - vertices
    turn = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1,
                                                                                   axis=0)[:, 0]
    if not np.all(turn > 0):
        raise fields.error(
            "vertices_m", "the polygon must be convex and counter-clockwise (no repeated points)"
        )
    return vertices


def _centred(vertices: np.ndarray) -> tuple[tuple[float, float], ...]:
    """Shift a polygon so that its area centroid is at the origin."""
    x, y = vertices[:, 0], vertices[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = cross.sum() / 2
    cx = ((x + xn) * cross).sum() / (6 * area)
    cy = ((y + yn) * cross).sum() / (6 * area)
    return tuple((float(px - cx), float(py - cy)) for px, py in vertices)
