"""Likelihood of independent motion at a flow measurement (section 2, eqs. 5-6, and beyond).

Three cues, each a probability-like value in [0, 1] (0 = consistent with the
static scene), combined as ``detection.likelihood`` says:

* **direction** (eqs. 5-6): angle alpha between the measured translational flow
  ``x_cur - H x_prev`` (measured flow minus F_R of the refined rotation) and the
  direction a static point's flow must have there, away from the epipole for
  forward motion. Eq. 6 as printed, ``1 - N(alpha; 0, sigma_l)``, goes negative
  when ``sigma_l < 1/sqrt(2 pi)`` (about 23 degrees, i.e. for every well measured
  flow); we divide the Gaussian by its peak instead, ``1 - exp(-alpha^2 / 2
  sigma_l^2)``: the same soft threshold, 0 at alpha = 0, rising with alpha, in
  [0, 1) for every sigma_l.
* **magnitude** (beyond the paper, for constant-bearing collision courses): below
  the horizon a static point is at most as far as the road point seen at its
  pixel, so its translational flow is at least as long as the road's. A flow much
  shorter than that bound (projected on the static direction) is independent motion.
* **standstill**: with no translation, no direction exists; the residual flow
  magnitude ``|x_cur - H x_prev|`` flags motion instead.

Degenerate cases, handled explicitly:

* near the epipole (``d_e < EPIPOLE_RADIUS_PX``) and for near-zero flow
  (``d_l < MIN_FLOW_PX``) the direction is undefined: the direction cue is 0;
* eq. 5's ``arcsin(sigma / d)`` is continued past ``sigma > d`` as
  ``(pi/2) sigma / d``, so a flow shorter than its own noise gets an ever wider
  sigma_l and an ever weaker direction cue instead of a NaN;
* above the horizon there is no road behind the pixel: the magnitude cue takes the
  depth of the pixel's foot point, the bottom of the previous p(x) region it stands on
  (:func:`foot_points`; at most ``FOOT_MAX_HEIGHT_M`` above the road), and is 0 where there
  is none; without a metric translation (CAN missing) it is 0;
* where the road's static flow (a lower bound of any static flow there) is longer
  than ``max_flow_px``, pyramidal LK cannot have measured it: both cues are 0;
* at a standstill only the standstill cue is used, whatever the mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import DetectionConfig
from appliance.vision.geometry import FloatArray

MIN_RAY_DROP = 1e-6        # a ray must point down the road normal by this much to meet the road
MIN_FLOW_PX = 0.15         # px, translational flow shorter than this has no usable direction
EPIPOLE_RADIUS_PX = 12.0   # px, within this distance of the epipole the direction is undefined
FOOT_MAX_HEIGHT_M = 2.0    # m, no road user is taller: a pixel higher above its foot has none


@dataclass(frozen=True)
class CameraMotion:
    """Camera motion used by the likelihood: ``X_cur = R X_prev + t``.

    R: (3, 3); t_dir: (3,) unit translation direction (ignored at a standstill);
    t_m: (3,) metric translation (m) or None when its length is unknown;
    K: (3, 3) intrinsics (ideal pixels).
    """

    R: FloatArray
    t_dir: FloatArray
    t_m: FloatArray | None
    standstill: bool
    K: FloatArray


@dataclass(frozen=True)
class RoadPlane:
    """The road in the current camera frame: unit ``normal`` (3,) pointing up, camera height (m)."""

    normal: FloatArray
    height_m: float


@dataclass(frozen=True)
class Cues:
    """Per-measurement cues (N,) in [0, 1]; ``direction``/``magnitude`` are None at a standstill."""

    direction: FloatArray | None
    magnitude: FloatArray | None
    standstill: FloatArray | None


def derotate(K: FloatArray, R: FloatArray, x_prev: NDArray[np.floating]) -> FloatArray:
    """``H x_prev`` (N, 2) with ``H = K R K^-1``: where the rotation alone moves each pixel."""
    x = np.asarray(x_prev, dtype=np.float64).reshape(-1, 2)
    H = K @ R @ np.linalg.inv(K)
    q = x @ H[:, :2].T + H[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        return q[:, :2] / q[:, 2:3]


def ray_drop(road: RoadPlane, K: FloatArray, uv: NDArray[np.floating]) -> FloatArray:
    """``n . ray`` (N,) for the rays (z = 1) of ideal pixels ``uv`` (N, 2): negative below
    the horizon (the ray meets the road at depth ``-h / drop``); a point at depth Z on the
    ray is ``h + Z drop`` above the road."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    rx = (uv[:, 0] - K[0, 2]) / K[0, 0]
    ry = (uv[:, 1] - K[1, 2]) / K[1, 1]
    return np.asarray(rx * road.normal[0] + ry * road.normal[1] + road.normal[2])


def road_depth(road: RoadPlane, K: FloatArray, uv: NDArray[np.floating]) -> FloatArray:
    """Depth Z (m, camera z) of the road point seen at ideal pixels ``uv`` (N, 2); NaN above the horizon."""
    drop = ray_drop(road, K, uv)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(drop < -MIN_RAY_DROP, -road.height_m / drop, np.nan)


def _angular_error(sigma: float | FloatArray, d: FloatArray) -> FloatArray:
    """``arcsin(sigma / d)`` of eq. 5, continued as ``(pi/2) sigma / d`` beyond sigma = d (rad)."""
    with np.errstate(divide="ignore"):
        ratio = sigma / np.maximum(d, 1e-12)
    return np.where(ratio <= 1.0, np.arcsin(np.minimum(ratio, 1.0)), 0.5 * np.pi * ratio)


def direction_cue(flow_t: FloatArray, static_dir: FloatArray, d_e: FloatArray,
                  cfg: DetectionConfig, sigma_p: FloatArray | None = None) -> FloatArray:
    """Eqs. 5-6: flow_t (N, 2) translational flow, static_dir (N, 2) direction a static
    point's flow must have, d_e (N,) distance to the epipole (px; inf when at infinity);
    sigma_p (N,) px: each flow's std across the static direction (``cfg.sigma_p_px`` if None)."""
    d_l = np.hypot(flow_t[:, 0], flow_t[:, 1])
    cross = flow_t[:, 0] * static_dir[:, 1] - flow_t[:, 1] * static_dir[:, 0]
    dot = flow_t[:, 0] * static_dir[:, 0] + flow_t[:, 1] * static_dir[:, 1]
    alpha = np.arctan2(np.abs(cross), dot)
    sp = cfg.sigma_p_px if sigma_p is None else sigma_p
    sigma_l = _angular_error(cfg.sigma_e_px, d_e) + _angular_error(sp, d_l)  # eq. 5
    p = 1.0 - np.exp(-alpha**2 / (2.0 * sigma_l**2))                                   # eq. 6
    defined = (d_l >= MIN_FLOW_PX) & (d_e >= EPIPOLE_RADIUS_PX)
    return np.where(defined & np.isfinite(p), p, 0.0)


def road_static_flow(x_cur: FloatArray, motion: CameraMotion, road: RoadPlane | None,
                     foot: FloatArray | None = None,
                     max_height_m: float = FOOT_MAX_HEIGHT_M) -> FloatArray:
    """Translational flow (N, 2) px of a road point seen at ``x_cur``: the shortest static flow there.

    A static point seen at ``x_cur`` at depth Z has ``f_s = ((K t)_xy - t_z x_cur) / (Z - t_z)``
    (t metric). Below the horizon nothing static is farther than the road, so with Z the
    road depth this is a lower bound on the length of any static flow at that pixel.
    NaN above the horizon, without a road model or without a metric translation; with
    ``foot`` (N, 2) ideal px (NaN: none), a pixel above the horizon takes the road depth of
    its foot point instead (an upright object standing there, its depth that of its foot),
    if the pixel is then at most ``max_height_m`` above the road (no road user is taller).
    """
    n = x_cur.shape[0]
    if motion.t_m is None or road is None:
        return np.full((n, 2), np.nan)
    K, t = motion.K, motion.t_m
    Z = road_depth(road, K, x_cur)
    if foot is not None:  # above the horizon: the depth of the object's foot point below
        Zf = road_depth(road, K, foot)
        with np.errstate(invalid="ignore"):   # height above the road at the foot's depth
            upright = road.height_m + Zf * ray_drop(road, K, x_cur) <= max_height_m
        Z = np.where(np.isnan(Z) & upright, Zf, Z)
    return static_flow(x_cur, K, t, Z)


def static_flow(x_cur: FloatArray, K: FloatArray, t: FloatArray, Z: FloatArray) -> FloatArray:
    """Translational flow (N, 2) px of static points seen at ideal pixels ``x_cur`` (N, 2) at
    depths ``Z`` (N,) m in the current frame, for the metric translation ``t`` (3,):
    ``((K t)_xy - t_z x_cur) / (Z - t_z)``; NaN where the point was not in front of the camera."""
    Kt = K @ t
    with np.errstate(divide="ignore", invalid="ignore"):
        depth_prev = Z - t[2]
        f_s = (Kt[:2][None, :] - t[2] * x_cur) / depth_prev[:, None]
    return np.where((depth_prev > 0.0)[:, None], f_s, np.nan)


def magnitude_cue_from_static(flow_t: FloatArray, f_s: FloatArray, cfg: DetectionConfig,
                              sigma_p: FloatArray | None = None,
                              relative: FloatArray | None = None) -> FloatArray:
    """Cue from the deficit ``delta = |f_s| - flow_t . f_s / |f_s|`` (px) of the measured flow.

    Its std is ``hypot(r |f_s|, sigma_p)`` (sigma_p (N,) px: each flow's std along ``f_s``,
    ``cfg.sigma_p_px`` if None; r (N,): the road flow's relative std, ``cfg.magnitude_sigma``
    if None); cue ``1 - exp(-delta+^2 / 2 std^2)``; 0 where ``f_s`` is NaN (no road behind
    the pixel, no metric translation).
    """
    sp = cfg.sigma_p_px if sigma_p is None else sigma_p
    rel = cfg.magnitude_sigma if relative is None else relative
    with np.errstate(divide="ignore", invalid="ignore"):
        length = np.hypot(f_s[:, 0], f_s[:, 1])
        along = (flow_t[:, 0] * f_s[:, 0] + flow_t[:, 1] * f_s[:, 1]) / length
        deficit = np.maximum(length - along, 0.0)
        std = np.hypot(rel * length, sp)
        p = 1.0 - np.exp(-deficit**2 / (2.0 * std**2))
    return np.where(np.isfinite(p), p, 0.0)


def magnitude_cue(flow_t: FloatArray, x_cur: FloatArray, motion: CameraMotion, road: RoadPlane,
                  cfg: DetectionConfig) -> FloatArray:
    """Flow-length cue at measurements ending at ``x_cur`` (N, 2): how much shorter than the
    road's static flow (:func:`road_static_flow`) the measured translational flow is."""
    return magnitude_cue_from_static(flow_t, road_static_flow(x_cur, motion, road), cfg)


def standstill_cue(flow_t: FloatArray, cfg: DetectionConfig) -> FloatArray:
    """``1 - 2^-(r / r0)^2`` for residual flow length r: 0.5 at ``standstill_residual_px``."""
    r = np.hypot(flow_t[:, 0], flow_t[:, 1]) / cfg.standstill_residual_px
    return np.where(np.isfinite(r), 1.0 - np.exp2(-(r**2)), 0.0)


def flow_std(flow_cov: FloatArray | None, static_dir: FloatArray, cfg: DetectionConfig
             ) -> tuple[FloatArray | None, FloatArray | None]:
    """Each flow's std (px) across and along the static direction, or (None, None).

    ``sigma_p`` of eq. 5 is "the accuracy of the tracking process"; the paper gives one
    number for every flow. Here each flow gets ``sqrt(sigma_p^2 + d^T C d)`` with C (N, 3)
    px^2 its error covariance ``[c_uu, c_uv, c_vv]`` (:func:`~appliance.vision.flow.fb_covariance`)
    and d the unit vector across / along the static direction (C None: the paper's
    constant sigma_p).
    """
    if flow_cov is None:
        return None, None
    n = np.hypot(static_dir[:, 0], static_dir[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        du, dv = static_dir[:, 0] / n, static_dir[:, 1] / n
    du = np.where(np.isfinite(du), du, 1.0)
    dv = np.where(np.isfinite(dv), dv, 0.0)
    c_uu, c_uv, c_vv = flow_cov[:, 0], flow_cov[:, 1], flow_cov[:, 2]
    with np.errstate(invalid="ignore"):
        along = c_uu * du * du + 2.0 * c_uv * du * dv + c_vv * dv * dv
        across = c_uu * dv * dv - 2.0 * c_uv * du * dv + c_vv * du * du
    sp2 = cfg.sigma_p_px ** 2

    def std(var: FloatArray) -> FloatArray:
        var = np.where(np.isnan(var), np.inf, np.maximum(var, 0.0))
        return np.sqrt(sp2 + var)

    return std(across), std(along)


def beyond_reach(f_s: FloatArray, cfg: DetectionConfig) -> NDArray[np.bool_]:
    """(N,) True where the road's static flow f_s (N, 2) px is longer than ``max_flow_px``."""
    with np.errstate(invalid="ignore"):
        return np.asarray(np.hypot(f_s[:, 0], f_s[:, 1]) > cfg.max_flow_px)


def motion_cues(x_prev: NDArray[np.floating], x_cur: NDArray[np.floating], motion: CameraMotion,
                road: RoadPlane | None, cfg: DetectionConfig,
                flow_cov: FloatArray | None = None, foot: FloatArray | None = None,
                length_cov: FloatArray | None = None) -> Cues:
    """All cues at N measurements ``x_prev -> x_cur`` (ideal pixels, (N, 2) each);
    flow_cov (N, 3) px^2: each flow's LK covariance (:func:`flow_std`), or None;
    length_cov: the covariance the flow-length cue takes instead, if given."""
    x_prev = np.asarray(x_prev, dtype=np.float64).reshape(-1, 2)
    x_cur = np.asarray(x_cur, dtype=np.float64).reshape(-1, 2)
    p = derotate(motion.K, motion.R, x_prev)
    flow_t = x_cur - p                                  # measured flow minus F_R
    if motion.standstill:
        return Cues(None, None, standstill_cue(flow_t, cfg))
    Kt = motion.K @ motion.t_dir
    static_dir = Kt[:2][None, :] - motion.t_dir[2] * p  # direction of static flow at p
    if abs(motion.t_dir[2]) > 1e-9:
        e = Kt[:2] / motion.t_dir[2]
        d_e = np.hypot(p[:, 0] - e[0], p[:, 1] - e[1])
    else:
        d_e = np.full(len(p), np.inf)
    s_across, s_along = flow_std(flow_cov, static_dir, cfg)
    if length_cov is not None:   # the flow-length cue's own std along the static flow
        s_along = flow_std(length_cov, static_dir, cfg)[1]
    direction = direction_cue(flow_t, static_dir, d_e, cfg, s_across)
    f_s = road_static_flow(x_cur, motion, road, foot)
    magnitude = magnitude_cue_from_static(flow_t, f_s, cfg, s_along)
    # where even the shortest static flow is beyond the reach of pyramidal LK, a measured
    # flow says nothing (typically the bottom of the image at speed): both cues are 0
    unreachable = beyond_reach(f_s, cfg)
    direction = np.where(unreachable, 0.0, direction)
    magnitude = np.where(unreachable, 0.0, magnitude)
    return Cues(direction, magnitude, None)


def combine(cues: Cues, mode: str) -> FloatArray:
    """Weight of each measurement for ``mode`` direction | magnitude | combined.

    ``combined`` is the noisy-OR ``1 - (1 - p_dir)(1 - p_mag)``: either cue alone can
    flag independent motion (crossing objects by direction, collision courses by length).
    """
    if cues.standstill is not None:
        return cues.standstill
    assert cues.direction is not None and cues.magnitude is not None
    if mode == "direction":
        return cues.direction
    if mode == "magnitude":
        return cues.magnitude
    if mode == "combined":
        return 1.0 - (1.0 - cues.direction) * (1.0 - cues.magnitude)
    raise ValueError(f"unknown likelihood mode {mode!r} (direction, magnitude or combined)")


def foot_points(p: NDArray[np.floating], scale: int, uv: NDArray[np.floating], threshold: float,
                height: int, gap_px: float) -> FloatArray:
    """Foot point (N, 2) image px of each pixel uv (N, 2), from the previous frame's p(x).

    In uv's column of the map (``scale`` px per cell), the run of cells with
    ``p >= threshold`` that contains uv or starts at most ``gap_px`` below it is the
    object uv stands on; its bottom edge is the foot point. NaN where no such run
    exists: a pixel is only given the depth of an object it touches, so the region
    grows up an object frame by frame instead of jumping to a facade far above it.
    Vectorised: per column, the next hit row and the next miss row at or below
    every row are running minima from the bottom.
    """
    hit = np.asarray(p) >= threshold
    h, w = hit.shape
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    out = np.full(uv.shape, np.nan)
    if not hit.any():
        return out
    rows = np.arange(h, dtype=np.int16)[:, None]     # int16: the running minima are 2x faster
    end = np.int16(h)
    next_hit = np.minimum.accumulate(np.where(hit, rows, end)[::-1], axis=0)[::-1]
    next_miss = np.minimum.accumulate(np.where(hit, end, rows)[::-1], axis=0)[::-1]
    inside = np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 1] >= 0)
    r = np.clip(np.where(inside, uv[:, 1], 0) // scale, 0, h - 1).astype(np.int64)
    c = np.clip(np.where(inside, uv[:, 0], 0) // scale, 0, w - 1).astype(np.int64)
    top = next_hit[r, c]
    ok = inside & (top < h) & ((top - r) * scale <= gap_px)
    bottom = next_miss[np.minimum(top, h - 1), c].astype(np.int64)   # first cell below the run
    out[ok, 0] = uv[ok, 0]
    out[ok, 1] = np.minimum(bottom[ok] * scale - 1, height - 1)
    return out
