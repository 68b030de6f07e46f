"""The flow-length cue measured over a longer baseline, where one frame's is too short to tell.

A mover on a collision course keeps its bearing: it sits near the epipole and its own flow
is little more than its expansion. What sets it apart from the static scene is that its
flow is shorter than the road's behind it (``likelihood.magnitude_cue``), and near the
epipole the road's flow is itself short: a pedestrian 28 m ahead and 30 px from the epipole,
the car at 34 km/h, 25 frames/s, has a road flow of 0.45 px per frame, about the accuracy of
one flow. Both the road's flow and the mover's shortfall grow with the distance driven,
while a flow's error hardly does; so where one frame's road flow is shorter than
``SHORT_FLOW_PX``, the flow is measured again from the frame about ``BASELINE_S`` earlier,
over the camera motion composed across those frames, and that measurement's cue replaces one
frame's. The search starts where the point's flow over one frame, scaled by the distance
driven, puts it (:func:`search_start`).

Over several frames three things that one frame's noise hides come out, and are kept out:

* a flow pointing back towards the epipole reads as a shortfall larger than the road's whole
  flow; near the epipole a small error of the composed rotation gives every pixel such a
  flow. The shortfall is read as at most the road's flow (a mover standing still in the image);
* just below the horizon the road's depth hangs on the road plane's pitch: its error adds
  ``ROAD_PITCH_STD_RAD / drop`` to the road flow's relative error (:func:`road_flow_error`);
* a feature sliding along a near edge against the far scene (a T-junction) moves
  consistently, and fast: a flow longer than the road's by more than its error
  (``SLOW_SIGMAS``) is not measured here (what this baseline is for barely moves).

The earlier frames' motions are the refined ones (rotation, and the translation direction
scaled by the CAN speed); where one is unknown (no metric translation) nothing is measured.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.vision.flow import FB_LENGTH_GAIN, fb_covariance, track
from appliance.vision.geometry import FloatArray, PinholeCamera
from appliance.vision.likelihood import (
    CameraMotion,
    RoadPlane,
    beyond_reach,
    derotate,
    flow_std,
    magnitude_cue_from_static,
    ray_drop,
    road_static_flow,
)

BASELINE_S = 0.18            # s, the longer baseline spans the most frames within this
                             #   (4 at 25 frames/s, 5 at 30)
SHORT_FLOW_PX = 1.5          # px, one frame's road flow shorter than this is measured again
SLOW_SIGMAS = 3.0            # a flow longer than the road's by this many stds is not measured
ROAD_PITCH_STD_RAD = 0.009   # rad, how far the road plane's pitch may be off (body pitch, mount)
SEARCH_LEVELS = 1            # pyramid levels of the search: it starts near its answer
HISTORY = 8                  # earlier frames kept (a baseline spans at most this + 1 frames)

Motion = tuple[FloatArray, FloatArray]   # (R (3, 3), t_m (3,) m): X_next = R X + t


@dataclass(frozen=True)
class PastFrame:
    """A frame before the current one: its image (8-bit gray), capture time (s) and the
    camera's motion from it to the frame after it (None: unknown, no metric translation)."""

    image: NDArray[np.uint8]
    t: float
    motion: Motion | None


def compose(past: tuple[PastFrame, ...]) -> Motion | None:
    """The camera's motion from the first of ``past`` (consecutive, oldest first) to the frame
    after the last: ``R = R_n ... R_1``, ``t = R_n (... (R_2 t_1 + t_2) ...) + t_n``; None where
    a motion is unknown."""
    R, t = np.eye(3), np.zeros(3)
    for f in past:
        if f.motion is None:
            return None
        Rf, tf = f.motion
        R, t = Rf @ R, Rf @ t + tf
    return R, t


def start_frame(past: tuple[PastFrame, ...], now: float) -> int | None:
    """Index in ``past`` of the earliest frame at most ``BASELINE_S`` before ``now``, if that is
    at least two frames back (one frame back is the short baseline itself)."""
    for i, f in enumerate(past[:-1]):
        if now - f.t <= BASELINE_S:
            return i
    return None


def longer_magnitude(past: tuple[PastFrame, ...], image: NDArray[np.uint8], t_now: float,
                     points: FloatArray, ideal: FloatArray, ideal_prev: FloatArray,
                     road: RoadPlane | None, short: CameraMotion, cfg: Config,
                     camera: PinholeCamera) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The flow-length cue (N,) at ``points`` (N, 2) px of the current frame measured over the
    longer baseline, and where it was (N,): points below the horizon whose road flow over one
    frame (motion ``short``) is shorter than ``SHORT_FLOW_PX``, tracked back to the baseline's
    first frame and forward-backward checked. ``ideal`` (N, 2): the same points as ideal
    pixels; ``ideal_prev`` (N, 2): where each was in the previous frame, ideal pixels (its flow
    over one frame). ``past`` is oldest first and ends with the
    previous frame (whose motion is ``short``'s). Above the horizon a pixel's depth is its foot
    point's only if it stands on the object below it; the background above a mover's head does
    not, and over several frames its flow falls far short of that depth's: those pixels keep
    one frame's cue."""
    n = len(points)
    cue, done = np.zeros(n), np.zeros(n, dtype=bool)
    i = start_frame(past, t_now)
    if i is None or short.standstill or road is None or short.t_m is None:
        return cue, done
    motion = compose(past[i:])
    if motion is None:
        return cue, done
    R, t_m = motion
    f_s = road_static_flow(ideal, short, road)
    with np.errstate(invalid="ignore"):
        pick = np.flatnonzero(np.hypot(f_s[:, 0], f_s[:, 1]) < SHORT_FLOW_PX)
    length = float(np.linalg.norm(t_m))
    if pick.size == 0 or length <= 0.0:
        return cue, done
    pts = points[pick]
    back = track(image, past[i].image, pts, np.ones(len(pts), dtype=bool),
                 dataclasses.replace(cfg.flow, pyramid_levels=min(cfg.flow.pyramid_levels,
                                                                   SEARCH_LEVELS)),
                 guess=search_start(camera, ideal[pick], ideal_prev[pick], short,
                                    R, length / float(np.linalg.norm(short.t_m))))
    long = CameraMotion(R=R, t_dir=t_m / length, t_m=t_m, standstill=False, K=camera.K)
    flow_t = ideal[pick] - derotate(camera.K, R, camera.undistort(back.end))
    f_s = road_static_flow(ideal[pick], long, road)
    _, s_along = flow_std(fb_covariance(back.fb_error, FB_LENGTH_GAIN), np.nan_to_num(f_s),
                         cfg.detection)
    relative = road_flow_error(ideal[pick], road, camera, cfg.detection.magnitude_sigma)
    magnitude = magnitude_cue_from_static(standing_still_at_most(flow_t, f_s), f_s, cfg.detection,
                                          s_along, relative)
    # a flow longer than the road's by more than its error: not measured (module docstring)
    length_s = np.hypot(f_s[:, 0], f_s[:, 1])
    error = np.hypot(relative * length_s, s_along)
    with np.errstate(invalid="ignore"):
        slow = np.hypot(flow_t[:, 0], flow_t[:, 1]) <= length_s + SLOW_SIGMAS * error
    ok = back.valid & slow
    cue[pick] = np.where(ok & ~beyond_reach(f_s, cfg.detection), magnitude, 0.0)
    done[pick] = ok
    return cue, done


def search_start(camera: PinholeCamera, ideal: FloatArray, ideal_prev: FloatArray,
                 short: CameraMotion, R: FloatArray, ratio: float) -> FloatArray:
    """Where (N, 2) px in the baseline's first frame the search for the ideal pixels ``ideal``
    (N, 2) starts: their translational flow over one frame (from ``ideal_prev``, motion
    ``short``) scaled by ``ratio``, the distance driven over the baseline over the last frame's,
    then the baseline's rotation R undone. A static point's flow grows with the distance driven,
    so the search starts near its answer: on a facade's windows, periodic every 20 px, a search
    started from the rotation alone 10 px away can settle on the next window, consistently
    both ways."""
    flow = ideal - derotate(camera.K, short.R, ideal_prev)
    unrotated = ideal - ratio * np.where(np.isfinite(flow), flow, 0.0)
    rays = np.column_stack([unrotated, np.ones(len(unrotated))]) @ camera.K_inv.T
    start = camera.project(rays @ R)        # R^T applied to each ray
    return np.where(np.isfinite(start), start, camera.project(rays))


def road_flow_error(uv: FloatArray, road: RoadPlane, camera: PinholeCamera,
                    magnitude_sigma: float) -> FloatArray:
    """Relative std (N,) of the road's flow at ideal pixels ``uv`` (N, 2): ``magnitude_sigma``
    and the road plane's pitch error. The road's depth is ``-h / drop`` with drop the ray's
    slope down the road's normal (:func:`likelihood.ray_drop`), so a pitch error e moves it
    by a share ``e / |drop|``: a pixel 8 px below the horizon (fx 586) sees the road at 95 m,
    and half a degree of pitch moves that by 63 %."""
    drop = np.abs(ray_drop(road, camera.K, uv))
    with np.errstate(divide="ignore"):
        return np.hypot(magnitude_sigma, ROAD_PITCH_STD_RAD / drop)


def standing_still_at_most(flow_t: FloatArray, f_s: FloatArray) -> FloatArray:
    """The translational flows (N, 2) less any part pointing back against the road's flow
    ``f_s`` (N, 2): the shortfall a flow shows is then at most the road's whole flow, that of a
    mover standing still in the image (module docstring)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        length = np.hypot(f_s[:, 0], f_s[:, 1])
        along = (flow_t[:, 0] * f_s[:, 0] + flow_t[:, 1] * f_s[:, 1]) / length
        back = np.minimum(np.where(np.isfinite(along), along, 0.0), 0.0)
        unit = np.where(length[:, None] > 0.0, f_s / length[:, None], 0.0)
    return flow_t - back[:, None] * np.nan_to_num(unit)
