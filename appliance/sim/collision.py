"""Footprint geometry in the ego vehicle frame: collision time and closest approach.

The ego outline is the rectangle ``-rear <= x <= front``, ``|y| <= width / 2``
in the road-level vehicle frame (ISO 8855, origin below the rear axle; the
body's bounce is ignored). A mover's footprint is its box's rectangle on the
ground. Everything is vectorised over time samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.sim.ego import EgoPath
from appliance.sim.movers import Trajectory

FloatArray = NDArray[np.float64]

GROUND_CLEARANCE_M = 0.12  # m: the ego drives over anything lower (a manhole cover, a speed bump)


@dataclass(frozen=True)
class Vehicle:
    """The ego outline, m: front bumper and rear bumper distance from the rear axle, width; and
    where the camera sits (vehicle frame, m)."""

    front: float
    rear: float
    width: float
    camera_x: float = 1.9
    camera_y: float = 0.0

    def corners(self) -> FloatArray:
        h = self.width / 2.0
        return np.array([[self.front, h], [-self.rear, h], [-self.rear, -h], [self.front, -h]])


def relative_pose(ego: EgoPath, traj: Trajectory, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Mover footprint centre (T, 2) and heading (T,) in the road-level vehicle frame at ``tau``."""
    ex, ey, epsi = ego.pose(tau)
    p = traj.position(tau)
    dx, dy = p[..., 0] - ex, p[..., 1] - ey
    c, s = np.cos(epsi), np.sin(epsi)
    centre = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)
    return centre, traj.heading(tau) - epsi


def relative_velocity(ego: EgoPath, traj: Trajectory, tau: FloatArray) -> FloatArray:
    """d/dt of the vehicle-frame footprint centre (T, 2), m/s: ``R^T (v_m - v_e) - w x p``."""
    centre, _ = relative_pose(ego, traj, tau)
    evx, evy = ego.velocity(tau)
    _, _, epsi = ego.pose(tau)
    w = ego.plan.yaw_rate_at(tau)
    v = traj.velocity(tau)
    dvx, dvy = v[..., 0] - evx, v[..., 1] - evy
    c, s = np.cos(epsi), np.sin(epsi)
    rx, ry = c * dvx + s * dvy, -s * dvx + c * dvy
    return np.stack([rx + w * centre[..., 1], ry - w * centre[..., 0]], axis=-1)


def footprint_corners(
    centre: FloatArray, heading: FloatArray, length: float, width: float
) -> FloatArray:
    """Corners (T, 4, 2) of rectangles with the given centres (T, 2) and headings (T,)."""
    c, s = np.cos(heading)[..., None], np.sin(heading)[..., None]
    lx = np.array([1, -1, -1, 1]) * length / 2.0
    ly = np.array([1, 1, -1, -1]) * width / 2.0
    return np.stack([centre[..., :1] + c * lx - s * ly, centre[..., 1:] + s * lx + c * ly], axis=-1)


def overlaps(corners: FloatArray, vehicle: Vehicle) -> NDArray[np.bool_]:
    """Separating-axis test of footprints (T, 4, 2) against the ego outline (touching counts)."""
    ego = vehicle.corners()
    inter = np.ones(corners.shape[0], bool)
    axes = [
        np.broadcast_to([1.0, 0.0], (corners.shape[0], 2)),
        np.broadcast_to([0.0, 1.0], (corners.shape[0], 2)),
        corners[:, 0] - corners[:, 1],
        corners[:, 1] - corners[:, 2],
    ]
    for ax in axes:
        pa = np.einsum("tkj,tj->tk", corners, ax)
        pb = ego @ ax.T  # (4, T)
        inter &= (pa.max(1) >= pb.min(0)) & (pb.max(0) >= pa.min(1))
    return inter


def _point_segment(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-12), 0.0, 1.0)
    out: FloatArray = np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)
    return out


def gap(corners: FloatArray, vehicle: Vehicle) -> FloatArray:
    """Distance (T,) m between footprints (T, 4, 2) and the ego outline; 0 where they overlap."""
    ego = np.broadcast_to(vehicle.corners(), corners.shape)
    d = np.full(corners.shape[0], np.inf)
    for A, B in ((corners, ego), (ego, corners)):
        for k in range(4):
            p = A[:, k]
            for e in range(4):
                d = np.minimum(d, _point_segment(p, B[:, e], B[:, (e + 1) % 4]))
    return np.where(overlaps(corners, vehicle), 0.0, d)


def collision_time(
    ego: EgoPath,
    traj: Trajectory,
    size: tuple[float, float, float],
    vehicle: Vehicle,
    tau_lo: float,
    tau_hi: float,
    dt: float = 0.002,
) -> float | None:
    """First tau in [tau_lo, tau_hi] at which the footprint touches the ego outline, or None.
    None for something lower than ``GROUND_CLEARANCE_M`` (``size[2]``): the car drives over it.

    Found on a ``dt`` grid and refined by bisection to 1e-7 s.
    """
    if size[2] < GROUND_CLEARANCE_M:
        return None
    tau = np.arange(tau_lo, tau_hi + dt, dt)

    def hit(t: FloatArray) -> NDArray[np.bool_]:
        c, h = relative_pose(ego, traj, t)
        return overlaps(footprint_corners(c, h, size[0], size[1]), vehicle)

    h = hit(tau)
    if not h.any():
        return None
    k = int(np.argmax(h))
    if k == 0:
        return float(tau[0])
    lo, hi = float(tau[k - 1]), float(tau[k])
    while hi - lo > 1e-7:
        mid = 0.5 * (lo + hi)
        if hit(np.array([mid]))[0]:
            hi = mid
        else:
            lo = mid
    return hi


def closest_approach(
    ego: EgoPath,
    traj: Trajectory,
    size: tuple[float, float, float],
    vehicle: Vehicle,
    tau_lo: float,
    tau_hi: float,
    dt: float = 0.005,
) -> tuple[float, float]:
    """(smallest gap m, its tau) between the footprint and the ego outline in [tau_lo, tau_hi]."""
    tau = np.arange(tau_lo, tau_hi + dt, dt)
    c, h = relative_pose(ego, traj, tau)
    g = gap(footprint_corners(c, h, size[0], size[1]), vehicle)
    k = int(np.argmin(g))
    return float(g[k]), float(tau[k])
