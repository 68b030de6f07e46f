"""Independently moving objects: pedestrians, cyclists, cars on piecewise-linear paths (and
things that stand still on the road: a box, a manhole cover, a painted arrow, a speed bump).

A :class:`Trajectory` is a list of waypoints ``(tau, x, y)`` in the world frame,
linear in between: constant velocity on each segment. Before the first waypoint
the mover stands at it; after the last it keeps the last segment's velocity
("if nobody braked"), which is what ``collision_t`` assumes.

The collision-course helpers build *exact* constant-velocity courses against
an ego vehicle that drives straight along the world x axis at constant speed:
the mover's footprint centre moves on the line that, relative to the ego,
passes through an aim point on the ego's outline. Seen from the car the
bearing to such a mover stays (nearly) constant: it grows in the image but
barely moves sideways (see shared/reference/collision-course.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# footprint length (along the heading), width and height, m
SIZES: dict[str, tuple[float, float, float]] = {
    "pedestrian": (0.35, 0.55, 1.75),
    "cyclist": (1.75, 0.6, 1.8),
    "car": (4.4, 1.8, 1.45),
    # things that never move: a crate left in the lane, and flat things on the road that the
    # car drives over (lower than collision.GROUND_CLEARANCE_M)
    "box": (0.5, 0.5, 0.5),
    "manhole": (0.7, 0.7, 0.01),
    "arrow": (3.0, 0.9, 0.01),
    "speed_bump": (0.5, 3.6, 0.07),
}


@dataclass(frozen=True)
class Trajectory:
    """Waypoints ``((tau_s, x_m, y_m), ...)`` with strictly increasing tau."""

    waypoints: tuple[tuple[float, float, float], ...]

    def __post_init__(self) -> None:
        taus = [w[0] for w in self.waypoints]
        if len(taus) < 2 or any(b <= a for a, b in zip(taus, taus[1:])):
            raise ValueError("a trajectory needs >= 2 waypoints with increasing times")

    @property
    def _arr(self) -> FloatArray:
        return np.array(self.waypoints, float)

    def _segment_velocities(self) -> FloatArray:
        w = self._arr
        return (w[1:, 1:] - w[:-1, 1:]) / (w[1:, :1] - w[:-1, :1])

    def position(self, tau: FloatArray | float) -> FloatArray:
        """Footprint centre (..., 2) at ``tau`` (world, m)."""
        tau = np.asarray(tau, float)
        w = self._arr
        x = np.interp(tau, w[:, 0], w[:, 1])
        y = np.interp(tau, w[:, 0], w[:, 2])
        v_last = self._segment_velocities()[-1]
        after = np.maximum(tau - w[-1, 0], 0.0)
        return np.stack([x + v_last[0] * after, y + v_last[1] * after], axis=-1)

    def velocity(self, tau: FloatArray | float) -> FloatArray:
        """World velocity (..., 2), m/s (the velocity of the segment containing tau)."""
        tau = np.asarray(tau, float)
        w = self._arr
        vel = self._segment_velocities()
        idx = np.clip(np.searchsorted(w[:, 0], tau, side="right") - 1, 0, len(vel) - 1)
        out = vel[idx]
        before = tau < w[0, 0]
        return np.where(before[..., None], 0.0, out)

    def heading(self, tau: FloatArray | float) -> FloatArray:
        """Heading (rad) of the box: the direction of travel; while standing, that of the
        nearest segment in which it moves."""
        tau = np.asarray(tau, float)
        w = self._arr
        vel = self._segment_velocities()
        moving = np.hypot(vel[:, 0], vel[:, 1]) > 1e-6
        if not moving.any():
            return np.zeros_like(tau)
        seg_heading = np.arctan2(vel[:, 1], vel[:, 0])
        # fill standing segments with the next (else previous) moving heading
        filled = seg_heading.copy()
        idx_moving = np.flatnonzero(moving)
        for i in range(len(vel)):
            if not moving[i]:
                nxt = idx_moving[idx_moving > i]
                filled[i] = seg_heading[nxt[0]] if len(nxt) else seg_heading[idx_moving[-1]]
        idx = np.clip(np.searchsorted(w[:, 0], tau, side="right") - 1, 0, len(vel) - 1)
        return filled[idx]

    def moves(self) -> bool:
        return bool(np.any(np.abs(self._segment_velocities()) > 1e-9))


@dataclass(frozen=True)
class MoverPlan:
    """One mover: its class (``SIZES`` key), trajectory and a short label."""

    kind: str
    trajectory: Trajectory
    label: str = ""


def crossing_course(
    *,
    ego_speed: float,
    aim_x: float,
    mover_speed: float,
    from_right: bool,
    aim_y: float,
    aim_tau: float,
    start_y: float,
    end_y: float,
) -> Trajectory:
    """A mover crossing the ego's path perpendicularly on an exact collision course.

    The ego drives along world +x at ``ego_speed`` m/s from x = 0 at tau = 0.
    The mover walks/rides along y (towards +y when ``from_right``) at
    ``mover_speed``; its footprint centre reaches the vehicle-frame point
    ``(aim_x, aim_y)`` at ``aim_tau`` (e.g. the front bumper at 25 % of the
    width, or the camera: then the bearing from the camera is exactly
    constant). It stands at lateral position ``start_y`` until it sets off and
    stops at ``end_y`` (which can lie beyond the car: the course is only cut by
    the collision).
    """
    sign = 1.0 if from_right else -1.0
    x_line = aim_x + ego_speed * aim_tau
    t_start = aim_tau - (aim_y - start_y) * sign / mover_speed
    t_end = aim_tau + (end_y - aim_y) * sign / mover_speed
    if not t_start < aim_tau < t_end:
        raise ValueError("start_y/end_y must lie before/after aim_y in the direction of travel")
    return Trajectory(((t_start, x_line, start_y), (t_end, x_line, end_y)))


def stand_then_cross(traj: Trajectory, stand_from: float) -> Trajectory:
    """Prepend a standing waypoint at ``stand_from`` (s) at the trajectory's start position."""
    t0, x0, y0 = traj.waypoints[0]
    if stand_from >= t0:
        return traj
    return Trajectory(((stand_from, x0, y0),) + traj.waypoints)


def stop_at(traj: Trajectory, stop_y: float, decel_s: float = 0.5) -> Trajectory:
    """The same course, but the mover stops at lateral position ``stop_y`` (decelerating over
    ``decel_s``, modelled as half speed for that time) and then stands."""
    (t0, x0, y0), (t1, _, y1) = traj.waypoints[0], traj.waypoints[1]
    vy = (y1 - y0) / (t1 - t0)
    t_stop = t0 + (stop_y - y0) / vy
    y_slow = stop_y - 0.5 * vy * decel_s
    t_slow = t_stop - 0.5 * decel_s
    pre = tuple(w for w in traj.waypoints if w[0] < t_slow and w[0] < t0 + 1e-9)
    return Trajectory(
        pre
        + (
            (t_slow, x0, y_slow),
            (t_slow + decel_s, x0, stop_y),
            (t_slow + decel_s + 60.0, x0, stop_y),
        )
    )
