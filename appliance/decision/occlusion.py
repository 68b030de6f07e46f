"""Is a lost track hidden, or gone? The flow in its coasted box says whether something nearer covers it.

A track the image tracker loses may be behind an occluder (a parked car, the paper's fig. 7)
or may simply have stopped: a pedestrian who stops at the kerb stops being independent
motion and its region fades. Coasting both at their last velocity warns for the second.
What tells them apart is depth: where the coasted object should be in the image, an
occluder is a static surface *nearer* than the object, so its translational flow is
longer than a static surface's at the object's depth would be; a stopped object (or the
background once it has gone) is at that depth or farther, its flow as long or shorter.

:func:`cover_ratio` measures this on a grid of points in the lower part of the coasted
box (an occluder hides the legs first; the head may show above a car's roof): Lucas-Kanade
from the current frame back to the previous one (forward-backward checked), the rotation
removed, and each translational flow projected on the static flow of the object's depth
(eq. of :func:`likelihood.static_flow`). Pure; the images come from the pipeline step.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig
from appliance.decision.tracking import ImageTrack
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.flow import flow_into
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix, in_image, lk_start
from appliance.vision.likelihood import derotate, static_flow

MIN_STATIC_FLOW_PX = 0.5   # points where the object's static flow is shorter carry no depth information
GRID = 6                   # points per side of the probe grid


def probe_points(box: tuple[float, float, float, float], width: int, height: int,
                 lower: float = 0.6, n: int = GRID) -> FloatArray:
    """A grid (M, 2) px over the lower ``lower`` fraction of ``box`` (u0, v0, u1, v1), inside the image."""
    u0, v0, u1, v1 = box
    v0 = v1 - lower * (v1 - v0)
    uu, vv = np.meshgrid(np.linspace(u0, u1, n + 2)[1:-1], np.linspace(v0, v1, n + 2)[1:-1])
    pts = np.column_stack([uu.ravel(), vv.ravel()])
    return pts[in_image(pts, width, height)]


def cover_ratio(prev: NDArray[np.uint8], cur: NDArray[np.uint8], box: tuple[float, float, float, float],
                depth_m: float, R: FloatArray, t_m: FloatArray, camera: PinholeCamera,
                flow_cfg: FlowConfig) -> tuple[float, int]:
    """Median ratio of the measured translational flow in ``box`` (current frame, px) to a static
    surface's at camera depth ``depth_m``, and the number of points it rests on (0: NaN ratio).

    R (3, 3), t_m (3,) m: the camera motion ``X_cur = R X_prev + t`` from the previous frame.
    About 1: what is there is at the object's depth (the object itself, stopped); below 1:
    farther (background: the object has gone); above 1: something nearer covers it.
    """
    pts = probe_points(box, camera.width, camera.height)
    if len(pts) == 0 or not np.all(np.isfinite(t_m)) or depth_m <= 0.0:
        return float("nan"), 0
    flow, valid = flow_into(prev, cur, pts, flow_cfg,
                            lk_start(camera, pts, R.T) if flow_cfg.rotation_guess else None)
    x_cur = camera.undistort(pts)
    x_prev = camera.undistort(pts - flow)
    flow_t = x_cur - derotate(camera.K, R, x_prev)
    f_s = static_flow(x_cur, camera.K, t_m, np.full(len(pts), depth_m))
    length2 = np.einsum("ij,ij->i", f_s, f_s)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.einsum("ij,ij->i", flow_t, f_s) / length2
        ok = valid & np.isfinite(ratio) & (length2 >= MIN_STATIC_FLOW_PX ** 2)
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


def coasted_cover(track: ImageTrack, foot: FloatArray | None,
                  images: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None, ego: EgoMotion,
                  sensors: SensorSample, dt: float, flow_cfg: FlowConfig,
                  camera: PinholeCamera) -> float:
    """:func:`cover_ratio` in the probe box of a coasted track (``lost_tracks.coasted_track``)
    whose ground position is ``foot`` (camera frame, m); NaN when it cannot be measured (no
    images, standstill, speed unknown, the box out of the image)."""
    speed = sensors.speed_m_s
    if images is None or foot is None or ego.standstill or not math.isfinite(speed) or foot[2] <= 0.5:
        return float("nan")
    u, v = float(track.x[0, 0]), float(track.x[1, 0])
    box = probe_box(u, v + 0.5 * track.size[1], track.size, float(foot[2]), camera)
    t_m = np.asarray(ego.translation_dir, dtype=np.float64) * speed * dt
    ratio, _ = cover_ratio(images[0], images[1], box, float(foot[2]), euler_to_matrix(ego.rotation),
                           t_m, camera, flow_cfg)
    return ratio
