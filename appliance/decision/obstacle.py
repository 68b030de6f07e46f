"""Anything standing in the path: a stopped car, a standing pedestrian, a box on the road.

Vision hands on the static scene's points in the image of the ego corridor with their depths
from motion parallax (``vision/parallax.py``, :class:`StandingPoints`). Here they become at
most one obstacle, the nearest:

1. **Standing in the path** (:func:`in_path`): each point in the vehicle frame (the camera's
   pose on the road), on the arc the car drives (CAN speed and yaw rate) no farther to the side
   than the warnings' corridor (half the vehicle's width plus ``warning.corridor_margin_m``),
   between ``obstacle.min_height_m`` and ``obstacle.clearance_m`` above the road (a bridge or an
   overhead sign is above that), nearer by ``DEPTH_SIGMAS`` of its depth's std than the road
   seen behind it, within the distance the car drives in ``warning.horizon_s``, keeping to its
   epipolar line (a point that moves on its own does not), and not on an object the detector
   already sees move (p(x), or a track moving over ground): those are the moving tracks'.
2. **The nearest group** (:func:`nearest_group`): the nearest ``obstacle.min_points`` of them
   within ``GROUP_DEPTH`` of each other along the path; its gap to the bumper is their median.
3. **Over frames** (:func:`obstacle_step`): a Kalman filter on the gap, predicted with the
   car's own travel (a standing object comes nearer by exactly what the car drives); confirmed
   after ``CONFIRM_FRAMES`` groups that agree with it, and then a track like any other, with an
   id of the tracker's and its threat: time to collision from the gap and the CAN speed (and
   the car's braking, where it brakes: a car that will stop short of it has none). Level 2
   only while the obstacle's middle lies within ``CORE_SHARE`` of the vehicle's half width of
   the path; an obstacle at the corridor's edge raises a caution at most. Entering a bend
   the path predicted from the yaw rate still runs straight, into the parked cars on the
   outside of the bend: those stand at its edge, a car stopped in the lane stands across it.

Pure functions of frozen data; no images.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from filterpy.kalman import predict, update
from numpy.typing import NDArray

from appliance.config import ObstacleConfig, WarningConfig
from appliance.decision.assess import TrackThreat
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import bearing
from appliance.messages import StandingPoints, TrackReport
from appliance.vision.geometry import FloatArray

DEPTH_SIGMAS = 3.0         # a point stands up when it is this many std nearer than the road behind it
MAX_RELATIVE_STD = 0.3     # a point whose depth's std is more than this share of it is not used
EPIPOLAR_MAX_PX = 1.0      # px, a static point keeps this close to its epipolar line
MOVER_PROBABILITY = 0.3    # p(x) at which a point is on a moving object (clustering's threshold)
GROUP_DEPTH = (1.5, 0.08)  # m + share of the range: the depth span of one obstacle's points
MEAN_SHIFT_STEPS = 2       # the group's span re-centred on its median this often
CONFIRM_FRAMES = 6         # agreeing groups before an obstacle is a confirmed track
MAX_MISSES = 8             # frames without a group before it is forgotten
GATE_SIGMAS = 3.0          # a group agrees with the obstacle within this many std (plus GATE_M)
GATE_M = 1.0
PROCESS_STD_M = 0.3        # m per frame, what the gap may change beyond the car's own travel
CORE_SHARE = 2.0 / 3.0     # level 2 needs the obstacle's middle this share of the half width off the path
BRAKING_M_S2 = -1.0        # m/s^2, the car counts as braking below this (CAN speed's slope)
ACCEL_TAU_S = 0.3          # s, low pass of that slope


@dataclass(frozen=True)
class Group:
    """The nearest obstacle's points this frame: gap (m, bumper to its near face along the
    path) and its std, box (u0, v0, u1, v1) px, its tallest point (m), how many."""

    gap: float
    std: float
    box: tuple[float, float, float, float]
    height: float
    n: int
    lateral: float = 0.0


@dataclass(frozen=True)
class Obstacle:
    """The tracked obstacle: ``x`` its gap (m) and ``P`` the variance (1, 1) m^2, the last
    group seen, hits (groups that agreed) and misses (frames since the last), id once
    confirmed."""

    x: FloatArray
    P: FloatArray
    group: Group
    hits: int = 1
    misses: int = 0
    id: int | None = None

    @property
    def gap(self) -> float:
        return float(self.x[0])


@dataclass(frozen=True)
class ObstacleState:
    """The obstacle (None: nothing stands in the path), the car's last CAN speed and its
    low-passed slope (m/s^2)."""

    obstacle: Obstacle | None = None
    speed: float | None = None
    accel: float = 0.0


def arc_coordinates(xy: FloatArray, curvature: float) -> tuple[FloatArray, FloatArray]:
    """Points (N, 2) of the vehicle frame -> (distance along the arc of ``curvature`` 1/m from
    the rear axle, lateral offset from it, left +), both (N,) m."""
    x, y = xy[:, 0], xy[:, 1]
    if abs(curvature) < 1e-5:
        return x.copy(), y.copy()
    r = 1.0 / curvature
    d = np.hypot(x, y - r)
    sign = math.copysign(1.0, curvature)
    lateral = sign * (abs(r) - d)
    s = np.arctan2(x, sign * (r - y)) * abs(r)
    return s, lateral


def in_path(pts: StandingPoints, f: FrameContext, prob: NDArray[np.float32], scale: int,
            mover_boxes: list[tuple[float, float, float, float]], cfg: ObstacleConfig,
            warning: WarningConfig
            ) -> tuple[NDArray[np.bool_], FloatArray, FloatArray, FloatArray]:
    """Which points stand up in the corridor (1. of the module docstring); their distance
    along the path from the rear axle (m), their height above the road (m) and their offset
    from the path (m, left +)."""
    n = len(pts.pixels)
    if n == 0:
        return np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0), np.zeros(0)
    R = f.pose.rotation()
    veh = pts.points @ R.T + np.asarray(f.pose.position)
    down = -((pts.points / pts.points[:, 2:3]) @ R.T)[:, 2]    # per metre of depth
    depth = pts.points[:, 2]
    with np.errstate(divide="ignore"):
        road = np.where(down > 1e-6, f.pose.position[2] / np.maximum(down, 1e-12), np.inf)
    height = veh[:, 2]
    speed = f.speed
    k = f.yaw_rate / speed if speed > 0.5 else 0.0
    s, lateral = arc_coordinates(veh[:, :2], k)
    half = 0.5 * f.mount.vehicle_width_m + warning.corridor_margin_m
    reach = f.mount.vehicle_front_m + max(speed, 0.0) * warning.horizon_s
    ok = (np.abs(lateral) <= half) & (s > f.mount.vehicle_front_m) & (s <= reach)
    ok &= (height >= cfg.min_height_m) & (height <= cfg.clearance_m)
    # nearer than the road seen behind it (above the horizon there is none), and known
    ok &= road - depth >= DEPTH_SIGMAS * pts.depth_std
    ok &= pts.depth_std <= MAX_RELATIVE_STD * depth
    ok &= pts.epipolar_px <= EPIPOLAR_MAX_PX
    rows, cols = prob.shape
    c = np.clip((pts.pixels[:, 0] // scale).astype(np.int64), 0, cols - 1)
    r = np.clip((pts.pixels[:, 1] // scale).astype(np.int64), 0, rows - 1)
    ok &= prob[r, c] < MOVER_PROBABILITY
    for u0, v0, u1, v1 in mover_boxes:
        ok &= ~((pts.pixels[:, 0] >= u0) & (pts.pixels[:, 0] <= u1)
                & (pts.pixels[:, 1] >= v0) & (pts.pixels[:, 1] <= v1))
    return ok, s, height, lateral


def nearest_group(pts: StandingPoints, standing: NDArray[np.bool_], s: FloatArray,
                  height: FloatArray, lateral: FloatArray, front_m: float, min_points: int
                  ) -> Group | None:
    """The nearest ``min_points`` standing points within ``GROUP_DEPTH`` of each other along the
    path (2. of the module docstring), with every standing point in that span, the span then
    centred on their median (``MEAN_SHIFT_STEPS``). ``lateral`` (N,): the points' offsets from
    the path (m)."""
    idx = np.flatnonzero(standing)
    if len(idx) < min_points:
        return None
    idx = idx[np.argsort(s[idx])]
    ss = s[idx]
    span = GROUP_DEPTH[0] + GROUP_DEPTH[1] * ss
    ends = np.searchsorted(ss, ss + span, side="right")
    first = np.flatnonzero(ends - np.arange(len(ss)) >= min_points)
    if len(first) == 0:
        return None
    i = int(first[0])
    members = idx[i:ends[i]]
    for _ in range(MEAN_SHIFT_STEPS):
        # the nearest span starts at the near tail of its points' depth noise: centred on
        # their median instead, it holds the obstacle's face
        centre = float(np.median(s[members]))
        half = 0.5 * (GROUP_DEPTH[0] + GROUP_DEPTH[1] * centre)
        members = idx[(ss >= centre - half) & (ss <= centre + half)]
    rel = pts.depth_std[members]
    px = pts.pixels[members]
    gap = float(np.median(s[members])) - front_m
    std = float(np.median(rel)) / math.sqrt(len(members))
    box = (float(px[:, 0].min()), float(px[:, 1].min()), float(px[:, 0].max()) + 1.0,
           float(px[:, 1].max()) + 1.0)
    return Group(gap=gap, std=std, box=box, height=float(height[members].max()), n=len(members),
                 lateral=float(np.median(lateral[members])))


def time_to_contact(gap: float, speed: float, accel: float) -> float | None:
    """Time (s) until the car has driven ``gap`` m at ``speed`` m/s, braking at ``accel`` m/s^2
    where that is below ``BRAKING_M_S2``; None when it stops short or stands."""
    if gap <= 0.0:
        return 0.0
    if speed <= 0.0:
        return None
    a = accel if accel < BRAKING_M_S2 else 0.0
    if a == 0.0:
        return gap / speed
    disc = speed * speed + 2.0 * a * gap
    if disc < 0.0:
        return None
    return (speed - math.sqrt(disc)) / -a


def obstacle_step(state: ObstacleState, pts: StandingPoints | None, f: FrameContext,
                  prob: NDArray[np.float32], scale: int,
                  mover_boxes: list[tuple[float, float, float, float]], cfg: ObstacleConfig,
                  warning: WarningConfig, next_id: int
                  ) -> tuple[ObstacleState, TrackThreat | None, int]:
    """One frame (3. of the module docstring): the new state, the confirmed obstacle's threat
    (None while nothing confirmed stands in the path) and the tracker's next id."""
    speed = f.speed
    accel = state.accel
    if state.speed is not None and f.dt > 0.0 and f.ego_known:
        a = (speed - state.speed) / f.dt
        w = 1.0 - math.exp(-f.dt / ACCEL_TAU_S)
        accel = (1.0 - w) * accel + w * a
    ob = state.obstacle
    if ob is not None:   # a standing object comes nearer by the car's own travel
        x, P = predict(ob.x, ob.P, np.eye(1), PROCESS_STD_M ** 2, u=np.array([speed * f.dt]),
                       B=-np.eye(1))
        ob = replace(ob, x=x, P=P)
    group = None
    if pts is not None and f.ego_known:
        standing, s, height, lateral = in_path(pts, f, prob, scale, mover_boxes, cfg, warning)
        group = nearest_group(pts, standing, s, height, lateral, f.mount.vehicle_front_m,
                              cfg.min_points)
    if group is not None:
        agrees = ob is not None and abs(group.gap - ob.gap) <= \
            GATE_SIGMAS * math.sqrt(float(ob.P[0, 0]) + group.std ** 2) + GATE_M
        if agrees and ob is not None:
            x, P = update(ob.x, ob.P, np.array([group.gap]), group.std ** 2, np.eye(1))
            ob = replace(ob, x=x, P=P, group=group, hits=ob.hits + 1, misses=0)
        elif ob is None or ob.misses > 0 or group.gap < ob.gap:
            ob = Obstacle(x=np.array([group.gap]), P=np.array([[group.std ** 2 + 1.0]]),
                          group=group)
        else:
            ob = replace(ob, misses=ob.misses + 1)
    elif ob is not None:
        ob = replace(ob, misses=ob.misses + 1)
    if ob is not None and (ob.misses > MAX_MISSES or ob.gap < -1.0):
        ob = None
    if ob is not None and ob.id is None and ob.hits >= CONFIRM_FRAMES:
        ob = replace(ob, id=next_id)
        next_id += 1
    new = ObstacleState(obstacle=ob, speed=speed, accel=accel)
    if ob is None or ob.id is None:
        return new, None, next_id
    g = ob.group
    ttc = time_to_contact(ob.gap, speed, accel)
    u0, v0, u1, v1 = g.box
    report = TrackReport(
        id=ob.id, bbox=g.box, probability=round(ob.hits / (ob.hits + ob.misses), 4),
        flow=(0.0, 0.0), ttc_s=None if ttc is None else round(ttc, 3),
        distance_m=round(max(ob.gap, 0.0), 2),
        bearing_rad=round(bearing(f.camera, (0.5 * (u0 + u1), 0.5 * (v0 + v1)), f.pose), 4))
    core = abs(g.lateral) <= CORE_SHARE * 0.5 * f.mount.vehicle_width_m
    threat = TrackThreat(report=report, on_course=True, on_course_wide=True, moving=False,
                         standing=True, speed_m_s=0.0, height_m=g.height,
                         ego_known=f.ego_known, max_level=2 if core else 1)
    return new, threat, next_id
