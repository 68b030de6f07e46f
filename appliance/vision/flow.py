"""Sparse optical flow: pyramidal Lucas-Kanade for both point pools, forward-backward check.

OpenCV's Python binding cannot take a prebuilt pyramid (``calcOpticalFlowPyrLK``
rejects the list ``buildOpticalFlowPyramid`` returns), so each frame's pyramid is
built once by tracking the particle pool and the static pool in *one* forward
call; the backward check is one more call.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig
from appliance.vision.geometry import FloatArray, in_image

CORNER_MIN_EIGENVALUE = 1e-3   # cornerMinEigenVal on 8-bit input; flat or black image: 0
CORNER_QUALITY = 0.01          # a candidate needs at least this fraction of the best cell's value

LK_MAX_ITERATIONS = 20         # LK iterations per pyramid level at most
LK_EPSILON_PX = 0.03           # px, LK stops once an iteration moves the window less than this
LK_MIN_EIGENVALUE = 1e-3       # smallest eigenvalue of a window's gradient matrix / pixels
                               #   (OpenCV's minEigThreshold): weaker texture is not tracked
FB_ERROR_GAIN = 15.0           # a flow's std grows by this times its forward-backward error (px)
FB_LENGTH_GAIN = 3.0           # the same for the flow-length cue (fb_covariance)


@dataclass(frozen=True)
class Tracks:
    """Result of :func:`track`: end points (M, 2) px, valid (M,) bool, fb_error (M,) px.

    ``fb_error`` is NaN where no backward check was made.
    """

    end: FloatArray
    valid: NDArray[np.bool_]
    fb_error: FloatArray


def lk_params(cfg: FlowConfig) -> dict[str, object]:
    """Keyword arguments of ``cv2.calcOpticalFlowPyrLK``: the ``[flow]`` section's window and
    pyramid, and this module's termination criteria."""
    return {
        "winSize": (cfg.window_px, cfg.window_px),
        "maxLevel": cfg.pyramid_levels,
        "criteria": (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, LK_MAX_ITERATIONS,
                     LK_EPSILON_PX),
        "minEigThreshold": LK_MIN_EIGENVALUE,
    }


def track(prev: NDArray[np.uint8], cur: NDArray[np.uint8], points: NDArray[np.floating],
          check_backward: NDArray[np.bool_], cfg: FlowConfig,
          guess: NDArray[np.floating] | None = None) -> Tracks:
    """Track ``points`` (M, 2) px from ``prev`` to ``cur`` (8-bit gray, same size).

    ``guess`` (M, 2) px: where LK starts in ``cur`` (``OPTFLOW_USE_INITIAL_FLOW``), for
    displacements beyond the pyramid's reach; the backward check then starts at
    ``points + end - guess``, the inverse guess, as far from its answer as the forward search was.

    One forward LK call for all points; one backward call for the points flagged in
    ``check_backward`` (M,), which stay valid only if they come back within
    ``cfg.fb_threshold_px``. A point is valid when LK converged (status 1, which
    includes OpenCV's minimum-eigenvalue test, so a flat or black image gives no
    valid points), the result is finite and its window (``window_px``) lies inside the
    image at both ends.
    """
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 1, 2))
    m = pts.shape[0]
    h, w = prev.shape[:2]
    if m == 0:
        return Tracks(np.zeros((0, 2)), np.zeros(0, dtype=bool), np.zeros(0))
    params = lk_params(cfg)
    init: NDArray[np.float32] | None = None
    if guess is not None:
        init = np.ascontiguousarray(np.asarray(guess, dtype=np.float32).reshape(-1, 1, 2))
        params["flags"] = cv2.OPTFLOW_USE_INITIAL_FLOW
    # OpenCV writes its answer into the initial-flow array: hand it a copy, the guess is needed below
    start = None if init is None else init.copy()
    nxt, status, _ = cv2.calcOpticalFlowPyrLK(prev, cur, pts, start, **params)  # type: ignore[call-overload]
    end = nxt.reshape(-1, 2).astype(np.float64)
    valid = status.reshape(-1).astype(bool) & np.all(np.isfinite(end), axis=1)
    # the LK window must lie inside both images: where it reaches over the border OpenCV
    # replicates the edge pixels, and a window half made of them barely moves (measured on
    # the simulator's bend: particles within 4 px of the left border kept flows of 0.2-0.5 px
    # where the road flows out of the image, and their flow-length cue 100+ particles, for
    # 16-18 frames)
    margin = cfg.window_px // 2
    valid &= in_image(end, w, h, margin) & in_image(pts.reshape(-1, 2), w, h, margin)
    fb_error = np.full(m, np.nan)
    back = np.flatnonzero(np.asarray(check_backward, dtype=bool) & valid)
    if back.size:
        fwd = np.ascontiguousarray(nxt[back])
        # with a guess, the backward search starts as far from the point as the forward one
        # ended from its guess (the inverse guess), not at the answer itself
        home = None if init is None else np.ascontiguousarray(fwd + (pts[back] - init[back]))
        ret, status_b, _ = cv2.calcOpticalFlowPyrLK(cur, prev, fwd, home, **params)  # type: ignore[call-overload]
        err = np.linalg.norm(ret.reshape(-1, 2) - pts[back].reshape(-1, 2), axis=1)
        fb_error[back] = err
        ok = status_b.reshape(-1).astype(bool) & (err < cfg.fb_threshold_px)
        valid[back] = ok
    return Tracks(end, valid, fb_error)


def flow_into(prev: NDArray[np.uint8], cur: NDArray[np.uint8], points: NDArray[np.floating],
              cfg: FlowConfig, guess: NDArray[np.floating] | None = None
              ) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The flow (M, 2) px that brought ``points`` (M, 2) of ``cur`` there from ``prev``, and
    where it is valid (M,): :func:`track` from ``cur`` back to ``prev``, every point
    forward-backward checked. For probing given pixels of the current frame. ``guess``
    (M, 2) px: where in ``prev`` to start looking (see :func:`track`)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    back = track(cur, prev, pts, np.ones(len(pts), dtype=bool), cfg, guess=guess)
    return pts - back.end, back.valid


def corner_candidates(gray: NDArray[np.uint8], cell_px: int) -> tuple[FloatArray, FloatArray]:
    """The best corner of every ``cell_px`` x ``cell_px`` cell: spread static-pool candidates.

    Shi-Tomasi strength (``cv2.cornerMinEigenVal``) on the half-resolution image; per
    cell the strongest pixel is kept if it is not flat (absolute floor) and at least
    ``CORNER_QUALITY`` of the best cell. Returns positions (C, 2) px in the full image
    and their strengths (C,). A flat or black image gives none.
    """
    half = np.asarray(cv2.pyrDown(gray))
    eig = np.asarray(cv2.cornerMinEigenVal(half, 3, ksize=3))
    c = max(2, cell_px // 2)
    h, w = eig.shape
    nr, nc = h // c, w // c
    if nr == 0 or nc == 0:
        return np.zeros((0, 2)), np.zeros(0)
    blocks = eig[: nr * c, : nc * c].reshape(nr, c, nc, c).transpose(0, 2, 1, 3).reshape(nr, nc, c * c)
    k = np.argmax(blocks, axis=-1)
    strength = np.take_along_axis(blocks, k[..., None], axis=-1)[..., 0].astype(np.float64)
    dr, dc = np.divmod(k, c)
    # half-resolution pixel i covers full-resolution pixels 2i and 2i + 1
    y = (np.arange(nr)[:, None] * c + dr) * 2.0 + 0.5
    x = (np.arange(nc)[None, :] * c + dc) * 2.0 + 0.5
    pos = np.column_stack([x.ravel(), y.ravel()])
    strength = strength.ravel()
    best = float(strength.max()) if strength.size else 0.0
    keep = (strength > CORNER_MIN_EIGENVALUE) & (strength >= CORNER_QUALITY * best)
    return pos[keep], strength[keep]


def fb_covariance(fb_error: NDArray[np.floating], gain: float = FB_ERROR_GAIN) -> FloatArray:
    """Each flow's error covariance (M, 3) ``[c_uu, c_uv, c_vv]`` px^2 from its forward-backward
    error (M,) px: ``(gain x fb_error)^2`` on both axes (NaN: not checked, counts 0).

    The forward-backward disagreement is a direct sample of a flow's error, and a small one
    stands for a much larger one: on road texture streaked along the image rows LK is wrong
    the same way in both directions (on the simulator's static bend the flows that look
    independent disagree by 0.15 px, median, while their true error is 1-3 px; flows on
    crossing cars and cyclists disagree by 0.01 px).

    The flow-length cue takes :data:`FB_LENGTH_GAIN` instead. What such errors feed is the
    direction cue: on static scenes 97-99 % of the flows that look independent do so by their
    direction, not their length (the length cue has the road's own relative error built in).
    And on a small mover every flow straddles a motion boundary, where LK's two directions
    disagree by 0.2-0.4 px because the window holds two motions, not because the flow is
    static: with the full gain a 10 px pedestrian on a collision course, seen only by its
    flow's length, gave no evidence for a second.
    """
    fb = np.asarray(fb_error, dtype=np.float64).reshape(-1)
    var = (gain * np.where(np.isfinite(fb), fb, 0.0)) ** 2
    return np.column_stack([var, np.zeros_like(var), var])
