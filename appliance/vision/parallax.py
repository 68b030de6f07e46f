"""Points of the static scene in the ego corridor, their depth from motion parallax.

A car standing in the lane is part of the static scene: the direction and flow-length cues
(likelihood.py) see nothing independent in it. But it stands up from the road. Seen from a
camera that drives forward, a static point moves away from the epipole by an amount that
depends only on its depth; over a baseline of several frames that parallax gives its depth,
and its depth at its pixel says how high above the road it is (the road at that pixel is
farther away than anything standing on it).

:func:`track_path_points` keeps Lucas-Kanade tracks of corners in the image of the ego
corridor (the road ahead along the arc of the CAN yaw rate, up to ``CLEARANCE_M`` above it),
chained frame to frame and forward-backward checked, for up to ``BASELINE_FRAMES`` frames; and
triangulates each from its oldest kept position and the camera motion since (the refined
rotation, the translation direction, the CAN speed for the length). Per point it hands on the
3-D point in the camera frame, its depth's std and its distance from the epipolar line (a
point that moves on its own does not keep to it). Whether points stand up in the corridor,
and where they form an obstacle, is the decision stage's (``decision/obstacle.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.messages import EgoMotion, SensorSample, StandingPoints
from appliance.vision.flow import track
from appliance.vision.geometry import (
    FloatArray,
    PinholeCamera,
    euler_to_matrix,
    lk_start,
    vehicle_from_camera_rotation,
)

BASELINE_FRAMES = 12     # frames a point's oldest kept position lies back (the parallax's baseline)
MAX_POINTS = 300         # tracks kept at once
SEED_SPACING_PX = 3      # px, new corners at least this far from each other and from the tracks
CLEARANCE_M = 2.5        # m, the corridor's image reaches this high above the road
TRACK_RANGE_M = (2.0, 90.0)  # m ahead of the bumper: a track is kept while in this corridor's image
SEED_RANGE_M = (12.0, 90.0)  # m ahead of the bumper: corners are seeded in this one's (nearer,
                             # its image holds the whole scene above the road behind it)
CORRIDOR_SEED_M = 0.6    # m, seeded this much wider than the vehicle on each side
LINK_STD_PX = 0.12       # px, the error one chained LK step adds to a track (random walk)
MIN_PARALLAX_PX = 0.3    # px, below this a point's depth is not computed
MIN_EPIPOLE_DISTANCE_PX = 12.0   # px, nor within this of the epipole (likelihood.py's radius)


@dataclass(frozen=True)
class PathPoints:
    """The tracks: ``history`` (N, BASELINE_FRAMES + 1, 2) px, the newest position last (NaN
    before a track's first frame); ``age`` (N,) frames tracked; ``motions`` the camera motion
    (R (3, 3), t (3,) m, ``X_cur = R X_prev + t``) of each of the last frames, newest last,
    None where its length was unknown (no CAN)."""

    history: FloatArray
    age: NDArray[np.int64]
    motions: tuple[tuple[FloatArray, FloatArray] | None, ...] = ()


def empty_path_points() -> PathPoints:
    return PathPoints(history=np.zeros((0, BASELINE_FRAMES + 1, 2)),
                      age=np.zeros(0, dtype=np.int64))


def no_points() -> StandingPoints:
    z = np.zeros((0, 3))
    return StandingPoints(pixels=np.zeros((0, 2)), points=z, depth_std=np.zeros(0),
                          epipolar_px=np.zeros(0), baseline=np.zeros(0, dtype=np.int64))


def corridor_mask(camera: PinholeCamera, cfg: Config, sensors: SensorSample,
                  attitude: FloatArray, span_m: tuple[float, float] = TRACK_RANGE_M
                  ) -> NDArray[np.uint8]:
    """The image of the ego corridor (255 inside): the road ahead along the arc of the CAN speed
    and yaw rate, ``CORRIDOR_SEED_M`` wider than the vehicle, from the road up to
    ``CLEARANCE_M``, between ``span_m`` ahead of the bumper."""
    m = cfg.mount
    pan = sensors.pan_rad if math.isfinite(sensors.pan_rad) else 0.0
    tilt = sensors.tilt_rad if math.isfinite(sensors.tilt_rad) else 0.0
    R_vc = vehicle_from_camera_rotation(m.pitch_rad, pan, tilt) @ attitude
    speed = sensors.speed_m_s if math.isfinite(sensors.speed_m_s) else 0.0
    yaw = sensors.yaw_rate_rad_s if math.isfinite(sensors.yaw_rate_rad_s) else 0.0
    k = yaw / speed if abs(speed) > 0.5 else 0.0
    s = m.vehicle_front_m + np.geomspace(span_m[0], span_m[1], 24)
    half = 0.5 * m.vehicle_width_m + CORRIDOR_SEED_M
    if abs(k) > 1e-6:
        cx, cy = np.sin(k * s) / k, (1.0 - np.cos(k * s)) / k
        nx, ny = -np.sin(k * s), np.cos(k * s)
    else:
        cx, cy, nx, ny = s, np.zeros_like(s), np.zeros_like(s), np.ones_like(s)
    mask = np.zeros((camera.height, camera.width), dtype=np.uint8)
    cam = np.array([m.x_m, m.y_m, m.z_m])
    for i in range(len(s) - 1):
        corners = []
        for j in (i, i + 1):
            for side in (-1.0, 1.0):
                for z in (0.0, CLEARANCE_M):
                    corners.append([cx[j] + side * half * nx[j], cy[j] + side * half * ny[j], z])
        P = (np.asarray(corners) - cam) @ R_vc      # camera frame: R_vc.T @ (p - cam)
        if np.any(P[:, 2] <= 0.5):
            continue
        uv = camera.project(P)
        if not np.all(np.isfinite(uv)):
            continue
        hull = cv2.convexHull(np.round(uv).astype(np.int32))
        cv2.fillConvexPoly(mask, hull, 255)
    return mask


def _seed(image: NDArray[np.uint8], mask: NDArray[np.uint8], tracks: FloatArray,
          margin: int) -> FloatArray:
    """New corners inside ``mask``, at least ``SEED_SPACING_PX`` from each other and from the
    tracks, up to ``MAX_POINTS`` tracks."""
    count = MAX_POINTS - len(tracks)
    if count <= 0:
        return np.zeros((0, 2))
    mask = mask.copy()
    h, w = mask.shape
    mask[:margin, :] = 0
    mask[h - margin:, :] = 0
    mask[:, :margin] = 0
    mask[:, w - margin:] = 0
    for u, v in np.round(tracks).astype(np.int64):
        cv2.circle(mask, (int(u), int(v)), SEED_SPACING_PX, 0, -1)
    if not mask.any():
        return np.zeros((0, 2))
    pts = cv2.goodFeaturesToTrack(image, maxCorners=count, qualityLevel=0.005,
                                  minDistance=SEED_SPACING_PX, mask=mask, blockSize=5)
    return np.zeros((0, 2)) if pts is None else pts.reshape(-1, 2).astype(np.float64)


def compose(motions: tuple[tuple[FloatArray, FloatArray] | None, ...], k: int
            ) -> tuple[FloatArray, FloatArray] | None:
    """The camera motion over the last ``k`` frames (``X_now = R X_then + t``), None when a
    step's length is unknown."""
    R, t = np.eye(3), np.zeros(3)
    for step in motions[::-1][:k]:
        if step is None:
            return None
        Rs, ts = step
        t = R @ ts + t       # X_now = R (Rs X + ts) + t
        R = R @ Rs
    return R, t


def triangulate(rays_then: FloatArray, rays_now: FloatArray, R: FloatArray, t: FloatArray
                ) -> tuple[FloatArray, FloatArray]:
    """Depths (N,) of static points in the current camera from two rays each (z = 1,
    (N, 3)) and the motion ``X_now = R X_then + t``: least squares of
    ``Z_now x_now - Z_then R x_then = t``; and the current point's distance from its epipolar
    line ``[t]x R x_then`` (eqs. 7-8, 11-13), in the normalised image plane."""
    a = rays_now
    b = -(rays_then @ R.T)
    aa, bb, ab = np.sum(a * a, 1), np.sum(b * b, 1), np.sum(a * b, 1)
    at, bt = a @ t, b @ t
    det = aa * bb - ab * ab
    with np.errstate(divide="ignore", invalid="ignore"):
        z_now = (bb * at - ab * bt) / det
        tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
        lines = (rays_then @ R.T) @ tx.T          # l = [t]x R x_then, per row
        d = np.abs(np.sum(lines * a, 1)) / np.hypot(lines[:, 0], lines[:, 1])
    return z_now, d


def track_path_points(state: PathPoints, prev: NDArray[np.uint8], cur: NDArray[np.uint8],
                      ego: EgoMotion, sensors: SensorSample, prev_sensors: SensorSample,
                      dt: float, attitude: FloatArray, cfg: Config, camera: PinholeCamera
                      ) -> tuple[PathPoints, StandingPoints]:
    """One frame: the tracks carried from ``prev`` to ``cur``, new ones seeded in the corridor,
    and the triangulated points of this frame (see the module docstring)."""
    R = euler_to_matrix(np.asarray(ego.rotation, dtype=np.float64))
    speed = 0.5 * (sensors.speed_m_s + prev_sensors.speed_m_s)
    known = (sensors.can_valid and math.isfinite(speed) and not ego.standstill and dt > 0.0
             and np.any(ego.translation_dir))
    step = (R, np.asarray(ego.translation_dir, float) * abs(speed) * dt) if known else None
    motions = (state.motions + (step,))[-BASELINE_FRAMES:]
    hist, age = state.history, state.age
    if len(hist):
        last = hist[:, -1]
        res = track(prev, cur, last, np.ones(len(last), dtype=bool), cfg.flow,
                    guess=lk_start(camera, last, R))
        keep = res.valid
        hist = np.concatenate([hist[keep, 1:], res.end[keep, None, :]], axis=1)
        age = age[keep] + 1
    mask = corridor_mask(camera, cfg, sensors, attitude)
    if len(hist):   # a track that left the corridor's image is no longer the corridor's
        uv = np.round(hist[:, -1]).astype(np.int64)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < camera.width) & (uv[:, 1] >= 0) \
            & (uv[:, 1] < camera.height)
        inside[inside] = mask[uv[inside, 1], uv[inside, 0]] > 0
        hist, age = hist[inside], age[inside]
    seed_mask = corridor_mask(camera, cfg, sensors, attitude, SEED_RANGE_M)
    new = _seed(cur, seed_mask, hist[:, -1] if len(hist) else np.zeros((0, 2)),
                cfg.flow.window_px // 2 + 1)
    if len(new):
        born = np.full((len(new), BASELINE_FRAMES + 1, 2), np.nan)
        born[:, -1] = new
        hist = np.concatenate([hist, born]) if len(hist) else born
        age = np.concatenate([age, np.zeros(len(new), dtype=np.int64)])
    state = PathPoints(history=hist, age=age, motions=motions)
    return state, standing_points(state, camera)


def standing_points(state: PathPoints, camera: PinholeCamera) -> StandingPoints:
    """Every track with a baseline of at least half ``BASELINE_FRAMES``, triangulated from its
    oldest kept position (:func:`triangulate`)."""
    base = np.minimum(state.age, BASELINE_FRAMES)
    use = np.flatnonzero(base >= BASELINE_FRAMES // 2)
    if len(use) == 0:
        return no_points()
    pixels, points, stds, epi, bases = [], [], [], [], []
    for k in np.unique(base[use]):
        motion = compose(state.motions, int(k))
        if motion is None:
            continue
        R, t = motion
        if float(np.linalg.norm(t)) < 1e-3:
            continue
        idx = use[base[use] == k]
        now = state.history[idx, -1]
        then = state.history[idx, -1 - int(k)]
        x_now, x_then = camera.rays(now), camera.rays(then)
        z, d = triangulate(x_then, x_now, R, t)
        # depth's std from the radial parallax about the epipole: Z = d r / (r' - r), so
        # sigma_Z / Z = sigma / (r' - r), the LK chain's error over k steps
        e = camera.K @ t
        if abs(e[2]) < 1e-9:
            continue
        epx = e[:2] / e[2]
        rot = x_then @ R.T
        then_px = np.column_stack([camera.fx * rot[:, 0] / rot[:, 2] + camera.cx,
                                   camera.fy * rot[:, 1] / rot[:, 2] + camera.cy])
        now_px = camera.undistort(now)
        r_then = np.linalg.norm(then_px - epx, axis=1)
        r_now = np.linalg.norm(now_px - epx, axis=1)
        # driving forward, a static point moves away from the epipole (a lead car driving
        # away moves towards it); near the epipole every motion is radial, and none tells
        parallax = r_now - r_then
        sigma = LINK_STD_PX * math.sqrt(float(k))
        ok = np.isfinite(z) & (z > 0.0) & (parallax >= MIN_PARALLAX_PX) \
            & (r_then >= MIN_EPIPOLE_DISTANCE_PX) & (t[2] < 0.0)
        pixels.append(now[ok])
        points.append(x_now[ok] * z[ok, None])
        stds.append(z[ok] * sigma / parallax[ok])
        epi.append(d[ok] * camera.fx)
        bases.append(np.full(int(np.count_nonzero(ok)), int(k)))
    if not pixels:
        return no_points()
    return StandingPoints(pixels=np.concatenate(pixels), points=np.concatenate(points),
                          depth_std=np.concatenate(stds), epipolar_px=np.concatenate(epi),
                          baseline=np.concatenate(bases).astype(np.int64))
