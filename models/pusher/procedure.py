"""Pushing procedures for the pusher-slider rig: seed 003's standard procedure (its Fig. 6)
and randomised variants, turned into carriage waypoints.

A procedure is a list of :class:`Stroke`; each stroke is defined in the object's frame *at
the moment the stroke starts* (as the paper's experimenter aimed each push at the block
where it lay). :func:`stroke_waypoints` turns one stroke into carriage waypoints: a transit
around the object from wherever the carriage is, an approach, the push, and a retreat.

The standard procedure (about 50 s with the default rig), after the paper's Fig. 6:
(a)-(d) straight two-finger pushes from the four sides, (e)-(f) two-finger pushes at two
opposite corners, (g)-(h) one-finger pushes off-centre (which turn the object).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from models.pose import wrap_angle

FINGERS = ("both", "one")
#: Gap (m) between the carriage's rods and the object's extreme point when a stroke starts.
APPROACH_STANDOFF_M = 0.02
#: How far (m) the carriage backs off after a push.
RETREAT_M = 0.03
#: Clearance (m) of the transit circle beyond the object's outline and the rods.
TRANSIT_CLEARANCE_M = 0.04
#: Fastest carriage turn (rad/s).
MAX_YAW_RATE = 1.0


@dataclass(frozen=True)
class Stroke:
    """One push, in the object's frame at the stroke's start.

    Attributes:
        direction_rad: push direction (rad) in the object frame.
        lateral_m: offset (m) of the pushing line from the object's centre, to the left of
            the push direction.
        fingers: ``"both"`` (the rods straddle the line) or ``"one"`` (one rod on the line,
            the other a spacing further from the centre, where it misses the object).
        distance_m: push distance (m) past the object's extreme point along the direction.
    """

    direction_rad: float
    lateral_m: float = 0.0
    fingers: str = "both"
    distance_m: float = 0.05

    def __post_init__(self) -> None:
        if self.fingers not in FINGERS:
            raise ValueError(f"fingers={self.fingers!r} is not one of {', '.join(FINGERS)}")
        if not 0.0 < self.distance_m <= 0.3:
            raise ValueError(f"distance_m={self.distance_m} is outside (0, 0.3] m")


def standard_procedure() -> list[Stroke]:
    """Seed 003's Fig. 6: four straight, two corner and two one-finger pushes."""
    d = np.deg2rad
    return [
        Stroke(d(0)), Stroke(d(90)), Stroke(d(180)), Stroke(d(270)),
        Stroke(d(45)), Stroke(d(225)),
        Stroke(d(0), lateral_m=0.025, fingers="one"),
        Stroke(d(180), lateral_m=0.025, fingers="one"),
    ]


def random_procedure(rng: np.random.Generator, strokes: int = 8) -> list[Stroke]:
    """A randomised variant: directions uniform on the circle, lateral offsets within
    +-2.5 cm, one-finger pushes 30% of the time, distances 3-7 cm."""
    out = []
    for _ in range(strokes):
        out.append(Stroke(float(rng.uniform(-np.pi, np.pi)),
                          lateral_m=float(rng.uniform(-0.025, 0.025)),
                          fingers="one" if rng.random() < 0.3 else "both",
                          distance_m=float(rng.uniform(0.03, 0.07))))
    return out


def stroke_waypoints(stroke: Stroke, object_pose: np.ndarray, footprint: np.ndarray,
                     carriage_pose: np.ndarray, *, spacing_m: float, rod_radius_m: float,
                     push_speed: float, transit_speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Carriage waypoints for one stroke, starting at ``carriage_pose``.

    Args:
        object_pose: (3,) the object's pose (x, y, theta) now (m, rad).
        footprint: (V, 2) its outline in its frame (m).
        carriage_pose: (3,) the carriage's (x, y, yaw) now.
        spacing_m, rod_radius_m: the rods' spacing and radius (m).
        push_speed, transit_speed: m/s.

    Returns:
        (durations (W,) s, poses (W, 3)): reach ``poses[i]`` ``durations[i]`` seconds after
        the previous waypoint, along straight lines (yaw unwrapped, so it turns the short
        way).
    """
    x, y, theta = object_pose
    centre = np.array([x, y])
    heading = theta + stroke.direction_rad
    u = np.array([np.cos(heading), np.sin(heading)])
    left = np.array([-u[1], u[0]])
    local_u = np.array([np.cos(stroke.direction_rad), np.sin(stroke.direction_rad)])
    back = float(np.max(footprint @ -local_u))  # extent of the object behind its centre
    lateral = stroke.lateral_m
    if stroke.fingers == "one":
        lateral += np.copysign(spacing_m / 2, stroke.lateral_m)
    start_xy = centre - (back + rod_radius_m + APPROACH_STANDOFF_M) * u + lateral * left
    end_xy = start_xy + (APPROACH_STANDOFF_M + stroke.distance_m) * u
    retreat_xy = end_xy - RETREAT_M * u

    radius = (float(np.max(np.linalg.norm(footprint, axis=1))) + spacing_m / 2 + rod_radius_m
              + TRANSIT_CLEARANCE_M)
    here = np.asarray(carriage_pose, dtype=float)
    yaw = here[2] + float(wrap_angle(heading - here[2]))
    points = [here]
    # out to the transit circle, round it, in to the start
    a0 = np.arctan2(here[1] - y, here[0] - x)
    a1 = np.arctan2(start_xy[1] - y, start_xy[0] - x)
    if np.linalg.norm(here[:2] - centre) < radius:
        points.append(np.array([*(centre + radius * np.array([np.cos(a0), np.sin(a0)])),
                                here[2]]))
    sweep = float(wrap_angle(a1 - a0))
    arc_steps = max(1, int(np.ceil(abs(sweep) / np.deg2rad(20))))
    for k in range(1, arc_steps + 1):
        a = a0 + sweep * k / arc_steps
        turn = here[2] + (yaw - here[2]) * k / arc_steps
        points.append(np.array([*(centre + radius * np.array([np.cos(a), np.sin(a)])), turn]))
    points += [np.array([*start_xy, yaw]), np.array([*end_xy, yaw]),
               np.array([*retreat_xy, yaw])]
    poses = np.array(points)
    speeds = np.full(len(poses), transit_speed)
    speeds[-2] = push_speed  # the approach and the push
    steps = np.diff(poses, axis=0)
    durations = np.maximum(np.linalg.norm(steps[:, :2], axis=1) / speeds[1:],
                           np.abs(steps[:, 2]) / MAX_YAW_RATE)
    durations = np.maximum(durations, 1e-3)
    return durations, poses[1:]
