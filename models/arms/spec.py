"""Manipulators in known static worlds, as data: which arm, which sensors, which obstacles,
how wrong the encoders are, and the commanded motion of an experiment (thesis sec. 5.4).

An arm file (``models/assets/arms/<name>.yaml`` or any path) has a ``kind``:

- ``planar``: a chain of revolute joints about z in the plane z = 0, links along each
  joint's x axis (``links_m``), every link covered by balls of ``link_radius_m`` (the
  arm's body for the frictionless projection out of penetration); sensors are balls at
  fractions along links (``sensors: [{link: i, at: t}]``, or ``spread: {links: [...],
  count: N}`` for N sensors evenly along those links); obstacles are spheres or boxes
  (``obstacles``). Joints have no limits (angles live on the circle).
- ``herb``: HERB's WAM and BarrettHand in a HERB scene (``scene``: a scene name or path;
  its obstacles and table are the environment, its movable object is left out); sensors
  and body balls are listed per link (``sensors: [{name, balls: [{link, center_m,
  radius_m}]}]``, or ``links: [...]`` to cover those links' collision geometry with
  balls, as the tactile patches are), ``body: [...]``), in the link's own frame;
  ``body_links`` names links
  whose Drake collision geometry is covered by balls automatically
  (:func:`models.arms.plant.geometry_balls`), so the arm the estimator models has the
  extent of the arm the physics simulates.

Both kinds share the noise and the experiment: ``offset_sd_rad`` (the encoder offset's
standard deviation per joint, Sigma_dq^(1/2) of sec. 5.4.1), ``proprio_noise_radius_rad``
(r_q: encoder noise uniform in a ball), ``sensor_error_rate`` (per sensor and step while
any sensor touches, the probability that a reading is flipped; the thesis gives
none for ch. 5, we choose 0.001 by default), ``free_false_positive_rate`` (the probability
of a contact reading while no sensor touches; default 0, the thesis' "perfectly
discriminative" sensors of sec. 4.4.1), ``contact_tolerance_m`` (a sensor is active
when its signed distance is at most this), ``press_depth_m`` (how deep a pressing arm
sinks into what it touches: the thesis' rigid model has 0; a simulated or real arm under
stiff position control pressing into compliant contact sits deeper, and its model must
let it, or every reading of two sensors touching at once is one the model cannot make),
``start_rad`` (the true start configuration)
and ``trajectory`` (commanded joint motion: ``[{to_rad: [...], steps: N}, ...]``, moved
in N equal steps from where the last segment ended).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from models.config import ConfigError, Fields, relative_to_file, resolve_asset

KINDS = ("planar", "herb")
OBSTACLE_SHAPES = ("sphere", "box")


@dataclass(frozen=True)
class Ball:
    """A ball rigidly attached to a link.

    Attributes:
        link: the body's name in the plant (planar arms: ``link_0``, ``link_1``, ...).
        center_m: (3,) centre in the body frame (m).
        radius_m: radius (m).
    """

    link: str
    center_m: tuple[float, float, float]
    radius_m: float


@dataclass(frozen=True)
class Sensor:
    """A binary contact sensor: a union of balls on the robot's surface (thesis sec. 5.3:
    ``G_s,i(q) = U_j B(c_ij(q), r_ij)``), listed, or covering the collision geometry of
    ``links`` (resolved against the plant: :func:`models.arms.plant.geometry_balls`)."""

    name: str
    balls: tuple[Ball, ...]
    links: tuple[str, ...] = ()


@dataclass(frozen=True)
class ObstacleSpec:
    """A static obstacle of a planar world.

    Attributes:
        shape: ``sphere`` (``radius_m``; 0 makes a point obstacle) or ``box`` (``size_m``).
        center_m: (3,) centre in the world (m).
        radius_m: sphere radius (m).
        size_m: (3,) box extents (m).
        yaw_rad: box rotation about z (rad).
    """

    name: str
    shape: str
    center_m: tuple[float, float, float]
    radius_m: float = 0.0
    size_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_rad: float = 0.0


@dataclass(frozen=True)
class TrajectorySegment:
    """Commanded motion to ``to_rad`` in ``steps`` equal joint steps."""

    to_rad: tuple[float, ...]
    steps: int


@dataclass(frozen=True)
class ArmSpec:
    """One manipulator in a known static world, with its sensing and its experiment.

    Attributes:
        name: arm name (``2dof``, ``3dof``, ``wam``).
        kind: ``planar`` or ``herb``.
        description: one line for humans.
        links_m: link lengths (m), planar arms only.
        link_radius_m: radius (m) of the balls covering a planar arm's links.
        scene: HERB scene name or path (``herb`` only).
        sensors: the binary contact sensors, in observation order.
        body: the non-sensing balls of the arm's body (with the sensors' balls, what the
            projection out of penetration keeps out of obstacles).
        body_links: links whose collision geometry adds non-sensing balls (``herb``).
        obstacles: a planar world's obstacles.
        offset_sd_rad: encoder offset standard deviation per joint (rad).
        proprio_noise_radius_rad: r_q, encoder noise radius (rad).
        sensor_error_rate: probability that a sensor's reading is flipped, per step, while
            any sensor touches.
        free_false_positive_rate: probability of a contact reading, per sensor and step,
            while no sensor touches.
        contact_tolerance_m: a sensor is active when its signed distance is at most this.
        press_depth_m: the depth (m) to which the projection out of penetration lets the
            arm's balls sink into what they press on (0: rigid, the thesis).
        start_rad: true start configuration (rad).
        trajectory: the commanded motion of the experiment.
        source: the file (for messages).
    """

    name: str
    kind: str
    description: str
    sensors: tuple[Sensor, ...]
    body: tuple[Ball, ...]
    offset_sd_rad: float
    proprio_noise_radius_rad: float
    sensor_error_rate: float
    free_false_positive_rate: float
    contact_tolerance_m: float
    start_rad: tuple[float, ...]
    trajectory: tuple[TrajectorySegment, ...]
    links_m: tuple[float, ...] = ()
    link_radius_m: float = 0.0
    scene: str | Path = ""
    obstacles: tuple[ObstacleSpec, ...] = ()
    body_links: tuple[str, ...] = ()
    press_depth_m: float = 0.0
    source: str = ""

    @property
    def dof(self) -> int:
        """Number of estimated joints."""
        return len(self.start_rad)

    def commanded_steps(self) -> np.ndarray:
        """(T, dof) commanded joint motion per step (rad), segment after segment."""
        q = np.array(self.start_rad)
        steps = []
        for segment in self.trajectory:
            target = np.array(segment.to_rad)
            steps.append(np.repeat(((target - q) / segment.steps)[None], segment.steps, 0))
            q = target
        return np.concatenate(steps)

    @staticmethod
    def load(name_or_path: str | Path) -> ArmSpec:
        """Load an arm by built-in name (``2dof``, ``3dof``, ``wam``) or path.

        Raises:
            ConfigError: naming the file and field of any malformed entry.
        """
        path = resolve_asset("arms", name_or_path)
        fields = Fields.from_file(path)
        kind = fields.string("kind", choices=KINDS)
        name = fields.string("name", path.stem)
        description = fields.string("description", "")
        if kind == "planar":
            links = _positive_list(fields, "links_m", 1, 0.01, 10.0)
            radius = fields.number("link_radius_m", min=1e-4, max=1.0)
            sensors = _planar_sensors(fields, links, radius)
            body = _planar_body(links, radius, sensors)
            obstacles = tuple(_obstacle(item, i) for i, item
                              in enumerate(fields.items("obstacles")))
            if not obstacles:
                raise fields.error("obstacles", "a planar world needs at least one obstacle")
            dof, extra = len(links), {"links_m": links, "link_radius_m": radius,
                                      "obstacles": obstacles}
        else:
            scene = relative_to_file(path, fields.string("scene"))
            sensors = tuple(_herb_sensor(item, i) for i, item
                            in enumerate(fields.items("sensors")))
            body = tuple(_ball(item) for item in fields.items("body", []))
            dof, extra = 7, {"scene": scene,
                             "body_links": tuple(fields.string_list("body_links", ()))}
        if not sensors:
            raise fields.error("sensors", "at least one sensor is needed")
        names = [s.name for s in sensors]
        if len(set(names)) != len(names):
            raise fields.error("sensors", f"sensor names must be distinct, got {names}")
        start = fields.vector("start_rad", dof, min=-2 * np.pi, max=2 * np.pi)
        trajectory = []
        for item in fields.items("trajectory"):
            trajectory.append(TrajectorySegment(
                item.vector("to_rad", dof, min=-2 * np.pi, max=2 * np.pi),
                item.number("steps", min=1, max=100000, integer=True)))
            item.done()
        if not trajectory:
            raise fields.error("trajectory", "at least one segment is needed")
        spec = ArmSpec(
            name=name, kind=kind, description=description, sensors=sensors, body=body,
            offset_sd_rad=fields.number("offset_sd_rad", min=0.0, max=10.0),
            proprio_noise_radius_rad=fields.number("proprio_noise_radius_rad", min=0.0,
                                                   max=1.0),
            sensor_error_rate=fields.number("sensor_error_rate", 0.001, min=1e-9, max=0.5),
            free_false_positive_rate=fields.number("free_false_positive_rate", 0.0, min=0.0,
                                                   max=0.5),
            contact_tolerance_m=fields.number("contact_tolerance_m", 0.001, min=1e-6,
                                              max=0.1),
            press_depth_m=fields.number("press_depth_m", 0.0, min=0.0, max=0.05),
            start_rad=start, trajectory=tuple(trajectory), source=str(path), **extra)
        fields.done()
        return spec


def _positive_list(fields: Fields, name: str, min_len: int, lo: float, hi: float
                   ) -> tuple[float, ...]:
    raw = fields.raw(name)
    if not isinstance(raw, list) or len(raw) < min_len:
        raise fields.error(name, f"expected a list of at least {min_len} numbers, got {raw!r}")
    return tuple(_number_in(fields, f"{name}[{i}]", v, lo, hi) for i, v in enumerate(raw))


def _number_in(fields: Fields, label: str, value, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or \
            not np.isfinite(value) or not lo <= value <= hi:
        raise fields.error(label, f"expected a number in [{lo}, {hi}], got {value!r}")
    return float(value)


def _planar_sensors(fields: Fields, links: tuple[float, ...], radius: float
                    ) -> tuple[Sensor, ...]:
    """Sensors at fractions along links, listed or spread evenly."""
    placements: list[tuple[int, float]] = []
    if fields.has("spread"):
        spread = fields.sub("spread")
        on = spread.raw("links")
        if not isinstance(on, list) or not on or any(
                isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(links)
                for k in on):
            raise spread.error("links", f"expected link indices in [0, {len(links) - 1}], "
                                        f"got {on!r}")
        count = spread.number("count", min=1, max=1000, integer=True)
        spread.done()
        total = sum(links[k] for k in on)
        for s in range(count):  # centres of count equal pieces of the chosen links' length
            along = (s + 0.5) * total / count
            for k in on:
                if along <= links[k] or k == on[-1]:
                    placements.append((k, min(along / links[k], 1.0)))
                    break
                along -= links[k]
    for item in fields.items("sensors", []):
        link = item.number("link", min=0, max=len(links) - 1, integer=True)
        placements.append((link, item.number("at", min=0.0, max=1.0)))
        item.done()
    return tuple(
        Sensor(f"s{i}", (Ball(f"link_{k}", (t * links[k], 0.0, 0.0), radius),))
        for i, (k, t) in enumerate(placements))


def _planar_body(links: tuple[float, ...], radius: float, sensors: tuple[Sensor, ...]
                 ) -> tuple[Ball, ...]:
    """Balls every ``radius`` along each link (the link's body), except where a sensor's
    ball already is."""
    taken = {(b.link, round(b.center_m[0] / radius)) for s in sensors for b in s.balls}
    body = []
    for k, length in enumerate(links):
        for x in np.linspace(0.0, length, int(np.ceil(length / radius)) + 1):
            if (f"link_{k}", round(x / radius)) not in taken:
                body.append(Ball(f"link_{k}", (float(x), 0.0, 0.0), radius))
    return tuple(body)


def _obstacle(item: Fields, index: int) -> ObstacleSpec:
    shape = item.string("shape", choices=OBSTACLE_SHAPES)
    name = item.string("name", f"obstacle_{index}")
    center = item.vector("center_m", 3, min=-10.0, max=10.0)
    if shape == "sphere":
        spec = ObstacleSpec(name, shape, center, radius_m=item.number("radius_m", min=0.0,
                                                                      max=10.0))
    else:
        spec = ObstacleSpec(name, shape, center, size_m=item.vector("size_m", 3, min=1e-4,
                                                                    max=20.0),
                            yaw_rad=np.deg2rad(item.number("yaw_deg", 0.0, min=-360,
                                                           max=360)))
    item.done()
    return spec


def _ball(item: Fields) -> Ball:
    ball = Ball(item.string("link"), item.vector("center_m", 3, min=-5.0, max=5.0),
                item.number("radius_m", min=1e-4, max=1.0))
    item.done()
    return ball


def _herb_sensor(item: Fields, index: int) -> Sensor:
    name = item.string("name", f"s{index}")
    balls = tuple(_ball(b) for b in item.items("balls", []))
    links = tuple(item.string_list("links", ()))
    if not balls and not links:
        raise item.error("balls", "a sensor needs balls or links")
    item.done()
    return Sensor(name, balls, links)


def check_links(spec: ArmSpec, link_names: set[str]) -> None:
    """Every ball's link must exist in the plant.

    Raises:
        ConfigError: naming the arm file, the sensor or body ball and the known links.
    """
    for label, links in [("body_links", spec.body_links)] + [
            (f"sensors[{s.name}].links", s.links) for s in spec.sensors]:
        for link in links:
            if link not in link_names:
                raise ConfigError(spec.source, label, f"unknown link {link!r}; the "
                                  f"robot's links: {', '.join(sorted(link_names))}")
    for label, balls in [(f"sensors[{s.name}]", s.balls) for s in spec.sensors] + [
            ("body", spec.body)]:
        for ball in balls:
            if ball.link not in link_names:
                raise ConfigError(spec.source, label, f"unknown link {ball.link!r}; the "
                                  f"robot's links: {', '.join(sorted(link_names))}")
