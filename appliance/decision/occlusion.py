"""Is a lost track hidden, or gone? The flow in its coasted box says whether something nearer covers it.

A track the image tracker loses may be behind an occluder (a parked car, the paper's fig. 7)
or may simply have stopped: a pedestrian who stops at the kerb stops being independent
motion and its region fades. Coasting both at their last velocity warns for the second.
What tells them apart is depth: where the coasted object should be in the image, an
occluder is a static surface *nearer* than the object, so its translational flow is
longer than a static surface's at the object's depth would be; a stopped object (or the
background once it has gone) is at that depth or farther, its flow as long or shorter.

:func:`cover_ratio` measures this on a grid of points in the lower part of the coasted
box (an occluder hides the legs first; the head may show above a car's roof): the flow there
(measured by vision, Lucas-Kanade from the current frame back to the previous one,
forward-backward checked), the rotation removed, and each translational flow projected on
the static flow of the object's depth (eq. of :func:`likelihood.static_flow`). Pure: the
probes name the pixels (:func:`cover_probe`, :func:`course_probe`), vision measures them.

Hidden, but is it still coming? A pedestrian who stops behind a parked car and one who walks
on are the same to the cover test; what tells them apart is what shows above the roof, the
head. On a collision course an object keeps its bearing, so its head barely moves in the
image (translational flow ~0, a ratio near 0), while a head that stopped moves like the static
scene at its depth (ratio 1) and the background behind it, farther, in between (on the
simulator's twins: 0.1 walking on, 0.6 slowing down, 1.0 stopped, 0.4-0.6 facade, per frame at
the true head). :func:`course_count` counts the points of a dense grid over the band where
the coasted object's head should be whose ratio is that low; the head is a few pixels wide, so
only the points whose Lucas-Kanade window holds it (within ~4 px) see it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from appliance.decision.tracking import ImageTrack
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix, in_image
from appliance.vision.likelihood import derotate, static_flow
from appliance.vision.probes import PointFlow

MIN_STATIC_FLOW_PX = 0.5   # points where the object's static flow is shorter carry no depth information
GRID = 6                   # points per side of the probe grid
HEAD_BAND_M = (0.5, 0.15)  # m below and above an object's top: the band its head is looked for in
HEAD_BAND_WIDTH_M = 1.2    # m, the band's width at least (a coasted position is off by a few px)
HEAD_GRID_PX = 1.5         # px between the band's points (a head 4-5 px wide is seen by ~4 px of them)
HEAD_GRID_MAX = (40, 30)   # points across and down at most (a near object: the spacing grows)
MIN_HEAD_POINTS = 3        # measured points a count needs
LOW_RATIO = 0.25           # a head-band point keeps its bearing when its translational flow is less than
                           # this share of a static point's at the object's depth (walking on: ~0.1,
                           # stopped: 1, the background behind it: 0.4-0.6)


@dataclass(frozen=True)
class CoastProbe:
    """Pixels (M, 2) of the current frame to measure for a hidden track, the object's camera
    depth (m) and the camera motion since the previous frame (R (3, 3), t_m (3,) m)."""

    points: FloatArray
    depth_m: float
    R: FloatArray
    t_m: FloatArray


def probe_points(box: tuple[float, float, float, float], width: int, height: int,
                 lower: float = 0.6, n: int = GRID) -> FloatArray:
    """A grid (M, 2) px over the lower ``lower`` fraction of ``box`` (u0, v0, u1, v1), inside the image."""
    u0, v0, u1, v1 = box
    v0 = v1 - lower * (v1 - v0)
    uu, vv = np.meshgrid(np.linspace(u0, u1, n + 2)[1:-1], np.linspace(v0, v1, n + 2)[1:-1])
    pts = np.column_stack([uu.ravel(), vv.ravel()])
    return pts[in_image(pts, width, height)]


def flow_ratios(pts: FloatArray, flow: PointFlow | None, depth_m: float, R: FloatArray,
                t_m: FloatArray, camera: PinholeCamera) -> FloatArray:
    """Per point (M,) of ``pts`` (current frame, px): its measured translational flow projected
    on a static surface's at camera depth ``depth_m``, over that flow's length; NaN where not
    measured or where the static flow is shorter than ``MIN_STATIC_FLOW_PX``.

    ``flow``: the flow vision measured at ``pts`` (None: not measured). R (3, 3), t_m (3,) m:
    the camera motion ``X_cur = R X_prev + t`` from the previous frame.
    """
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    if flow is None or len(pts) == 0 or not np.all(np.isfinite(t_m)) or depth_m <= 0.0:
        return np.full(len(pts), np.nan)
    x_cur = camera.undistort(pts)
    x_prev = camera.undistort(pts - flow.flow)
    flow_t = x_cur - derotate(camera.K, R, x_prev)
    f_s = static_flow(x_cur, camera.K, t_m, np.full(len(pts), depth_m))
    length2 = np.einsum("ij,ij->i", f_s, f_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.einsum("ij,ij->i", flow_t, f_s) / length2
    ok = flow.valid & np.isfinite(ratio) & (length2 >= MIN_STATIC_FLOW_PX ** 2)
    out: FloatArray = np.where(ok, ratio, np.nan)
    return out


def cover_ratio(p: CoastProbe, flow: PointFlow | None, camera: PinholeCamera) -> tuple[float, int]:
    """Median ratio of the measured translational flow at the probe's points to a static
    surface's at the object's depth (:func:`flow_ratios`), and the number of points it rests on
    (0: NaN ratio).

    About 1: what is there is at the object's depth (the object itself, stopped); below 1:
    farther (background: the object has gone); above 1: something nearer covers it.
    """
    ratio = flow_ratios(p.points, flow, p.depth_m, p.R, p.t_m, camera)
    ok = np.isfinite(ratio)
    if not np.any(ok):
        return float("nan"), 0
    return float(np.median(ratio[ok])), int(ok.sum())


def probe_box(u: float, v_bottom: float, size: tuple[float, float], depth_m: float,
              camera: PinholeCamera, min_width_m: float = 0.6, min_height_m: float = 1.2
              ) -> tuple[float, float, float, float]:
    """The box to probe for a coasted object: its image box (bottom centre ``u, v_bottom``,
    ``size`` w, h px) grown to at least ``min_width_m`` x ``min_height_m`` at ``depth_m``
    (a lost track's box is often a shrunken remnant: legs, or what the occluder left)."""
    w = max(size[0], min_width_m * camera.fx / depth_m)
    h = max(size[1], min_height_m * camera.fy / depth_m)
    return (u - 0.5 * w, v_bottom - h, u + 0.5 * w, v_bottom)


def _coasted_motion(foot: FloatArray | None, ego: EgoMotion, sensors: SensorSample, dt: float
                    ) -> tuple[float, FloatArray, FloatArray] | None:
    """The coasted object's camera depth (m) at its ground position ``foot`` (camera frame) and
    the camera motion (R (3, 3), t_m (3,) m) since the previous frame; None at a standstill,
    with the speed unknown or the object less than 0.5 m ahead."""
    speed = sensors.speed_m_s
    if foot is None or ego.standstill or not math.isfinite(speed) or foot[2] <= 0.5:
        return None
    t_m = np.asarray(ego.translation_dir, dtype=np.float64) * speed * dt
    return float(foot[2]), euler_to_matrix(ego.rotation), t_m


def cover_probe(track: ImageTrack, foot: FloatArray | None, ego: EgoMotion,
                sensors: SensorSample, dt: float, camera: PinholeCamera) -> CoastProbe | None:
    """The points of :func:`cover_ratio` in the probe box of a coasted track
    (``lost_tracks.coasted_track``) whose ground position is ``foot`` (camera frame, m); None
    when it cannot be measured (standstill, speed unknown)."""
    motion = _coasted_motion(foot, ego, sensors, dt)
    if motion is None:
        return None
    depth, R, t_m = motion
    u, v = float(track.x[0, 0]), float(track.x[1, 0])
    box = probe_box(u, v + 0.5 * track.size[1], track.size, depth, camera)
    return CoastProbe(probe_points(box, camera.width, camera.height), depth, R, t_m)


def head_band(u: float, v_bottom: float, width_px: float, height_m: float, depth_m: float,
              camera: PinholeCamera) -> tuple[float, float, float, float]:
    """The band (u0, v0, u1, v1) px where the head of an object ``height_m`` tall standing at
    image column ``u``, row ``v_bottom`` and ``depth_m`` should be: ``HEAD_BAND_M`` below and
    above its top, at least ``HEAD_BAND_WIDTH_M`` and ``width_px`` wide."""
    px_per_m = camera.fy / depth_m
    top = v_bottom - height_m * px_per_m
    half = 0.5 * max(width_px, HEAD_BAND_WIDTH_M * camera.fx / depth_m)
    return (u - half, top - HEAD_BAND_M[1] * px_per_m, u + half, top + HEAD_BAND_M[0] * px_per_m)


def band_points(box: tuple[float, float, float, float], width: int, height: int,
                spacing_px: float = HEAD_GRID_PX,
                most: tuple[int, int] = HEAD_GRID_MAX) -> FloatArray:
    """A grid (M, 2) px over ``box`` every ``spacing_px`` (at most ``most`` points across and
    down), inside the image."""
    u0, v0, u1, v1 = box
    nu = int(np.clip((u1 - u0) / spacing_px, 2, most[0]))
    nv = int(np.clip((v1 - v0) / spacing_px, 2, most[1]))
    uu, vv = np.meshgrid(np.linspace(u0, u1, nu), np.linspace(v0, v1, nv))
    pts = np.column_stack([uu.ravel(), vv.ravel()])
    return pts[in_image(pts, width, height)]


def course_probe(track: ImageTrack, foot: FloatArray | None, height_m: float, ego: EgoMotion,
                 sensors: SensorSample, dt: float, camera: PinholeCamera) -> CoastProbe | None:
    """The points of :func:`course_count` in the head band (:func:`head_band`) of a coasted
    track ``height_m`` tall whose ground position is ``foot`` (camera frame, m); None when it
    cannot be measured (standstill, speed unknown, height unknown)."""
    motion = _coasted_motion(foot, ego, sensors, dt)
    if motion is None or height_m <= 0.0:
        return None
    depth, R, t_m = motion
    u, v = float(track.x[0, 0]), float(track.x[1, 0])
    box = head_band(u, v + 0.5 * track.size[1], track.size[0], height_m, depth, camera)
    return CoastProbe(band_points(box, camera.width, camera.height), depth, R, t_m)


def course_count(p: CoastProbe, flow: PointFlow | None, camera: PinholeCamera,
                 low_ratio: float = LOW_RATIO) -> tuple[float, float]:
    """How many points of the head band have a flow ratio (:func:`flow_ratios`) below
    ``low_ratio``: something there keeps its bearing, as an object at the probe's depth on a
    collision course does; and their median column (px). NaN with fewer than
    ``MIN_HEAD_POINTS`` measured (count) or without such a point (column)."""
    ratio = flow_ratios(p.points, flow, p.depth_m, p.R, p.t_m, camera)
    ok = np.isfinite(ratio)
    if ok.sum() < MIN_HEAD_POINTS:
        return float("nan"), float("nan")
    low = ok & (ratio < low_ratio)
    column = float(np.median(p.points[low, 0])) if low.any() else float("nan")
    return float(low.sum()), column
