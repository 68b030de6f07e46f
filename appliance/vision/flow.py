"""Sparse optical flow: pyramidal Lucas-Kanade for both point pools, forward-backward check.

OpenCV's Python binding cannot take a prebuilt pyramid (``calcOpticalFlowPyrLK``
rejects the list ``buildOpticalFlowPyramid`` returns), so each frame's pyramid is
built once by tracking the particle pool and the static pool in *one* forward
call; the backward check of the points that need it is one more call.
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


GAUSSIAN_L1_TO_STD = 1.2533   # sqrt(pi / 2): std of a zero-mean Gaussian from its mean |x|
FLOW_PRIOR_STD_PX = 10.0      # px, what is known of a flow before its window is looked at


@dataclass(frozen=True)
class Tracks:
    """Result of :func:`track`: end points (M, 2) px, valid (M,) bool, fb_error (M,) px,
    residual (M,): LK's mean absolute patch difference after alignment (gray levels).

    ``fb_error`` is NaN where no backward check was made.
    """

    end: FloatArray
    valid: NDArray[np.bool_]
    fb_error: FloatArray
    residual: FloatArray


def lk_params(cfg: FlowConfig) -> dict[str, object]:
    """Keyword arguments of ``cv2.calcOpticalFlowPyrLK`` from the ``[flow]`` section."""
    return {
        "winSize": (cfg.window_px, cfg.window_px),
        "maxLevel": cfg.pyramid_levels,
        "criteria": (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, cfg.max_iterations,
                     cfg.epsilon),
        "minEigThreshold": cfg.min_eigenvalue,
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
        empty = np.zeros((0, 2))
        return Tracks(empty, np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0))
    params = lk_params(cfg)
    init: NDArray[np.float32] | None = None
    if guess is not None:
        init = np.ascontiguousarray(np.asarray(guess, dtype=np.float32).reshape(-1, 1, 2))
        params["flags"] = cv2.OPTFLOW_USE_INITIAL_FLOW
    # OpenCV writes its answer into the initial-flow array: hand it a copy, the guess is needed below
    start = None if init is None else init.copy()
    nxt, status, lk_err = cv2.calcOpticalFlowPyrLK(prev, cur, pts, start, **params)  # type: ignore[call-overload]
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
    with np.errstate(invalid="ignore"):   # OpenCV leaves the residual of lost points undefined
        residual = np.asarray(lk_err, dtype=np.float64).reshape(-1)
    residual = np.where(np.isfinite(residual) & valid, residual, np.inf)
    return Tracks(end, valid, fb_error, residual)


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


def flow_covariance(prev: NDArray[np.uint8], points: NDArray[np.floating],
                    residual: NDArray[np.floating], window_px: int) -> FloatArray:
    """Covariance (M, 3) ``[c_uu, c_uv, c_vv]`` px^2 of Lucas-Kanade flows from ``points``.

    LK is a least-squares fit of a shift to the patch: its covariance is the residual
    variance s^2 times the inverse of the window's gradient matrix
    ``G = sum [Ix^2, IxIy; IxIy, Iy^2]`` (gray levels / px, central differences of
    ``prev`` around each point rounded to the pixel grid), s taken from LK's mean absolute
    difference (M,) (gray levels) as for a Gaussian. With a weak prior on the flow
    (``FLOW_PRIOR_STD_PX``), ``C = s^2 (G + s^2 / prior^2 I)^-1`` stays finite: along an
    edge (the aperture problem) or in a flat window the flow is only known to about the
    prior. A point without a residual (LK lost it) gets the prior.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    m = pts.shape[0]
    if m == 0:
        return np.zeros((0, 3))
    h, w = prev.shape[:2]
    r = window_px // 2
    q = np.rint(pts).astype(np.int64)
    q[:, 0] = np.clip(q[:, 0], r + 1, w - r - 2)
    q[:, 1] = np.clip(q[:, 1], r + 1, h - r - 2)
    off = np.arange(-r - 1, r + 2)
    patch = prev[q[:, 1, None, None] + off[None, :, None],
                 q[:, 0, None, None] + off[None, None, :]].astype(np.float64)
    ix = 0.5 * (patch[:, 1:-1, 2:] - patch[:, 1:-1, :-2])
    iy = 0.5 * (patch[:, 2:, 1:-1] - patch[:, :-2, 1:-1])
    s2 = (GAUSSIAN_L1_TO_STD * np.asarray(residual, dtype=np.float64).reshape(-1)) ** 2
    known = np.isfinite(s2)
    s2 = np.where(known, s2, 1.0)
    eps = s2 / FLOW_PRIOR_STD_PX ** 2
    gxx = np.einsum("kij,kij->k", ix, ix) + eps
    gxy = np.einsum("kij,kij->k", ix, iy)
    gyy = np.einsum("kij,kij->k", iy, iy) + eps
    scale = s2 / (gxx * gyy - gxy * gxy)
    cov = np.column_stack([gyy * scale, -gxy * scale, gxx * scale])
    cov[~known] = (FLOW_PRIOR_STD_PX ** 2, 0.0, FLOW_PRIOR_STD_PX ** 2)
    return cov


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


def lk_covariance(prev: NDArray[np.uint8], points: NDArray[np.floating],
                  residual: NDArray[np.floating], window_px: int, residual_gain: float,
                  image_noise_gray: float, fb_error: NDArray[np.floating] | None = None,
                  fb_gain: float = 0.0) -> FloatArray | None:
    """Each flow's error covariance (M, 3) px^2 for the likelihood, or None when every term is off.

    ``residual_gain^2`` times :func:`flow_covariance` with LK's own residual, plus
    ``image_noise_gray^2 G^-1``: the covariance of a window with gradient matrix G under
    a fixed intensity noise (gray levels). The second term is what the aperture problem
    costs: on road texture streaked along the image rows (foreshortening) the column
    component of the flow is barely constrained, and measured LK errors across the
    epipolar line grow about as ``6 gray levels x sqrt(d^T G^-1 d)`` (median) on the
    simulator's bend, with a tail several times longer.

    Plus ``(fb_gain x fb_error)^2`` on both axes: the forward-backward disagreement
    (M,) px of each flow (NaN: not checked, counts 0) is a direct sample of its error.
    On the simulator's static bend the flows that look independent have a median FB
    error of 0.15 px against 0.01 px on the crossing car and cyclist, while their true
    error is 1-3 px: LK is consistently wrong both ways on streaky texture, so a small
    FB error stands for a much larger one.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    total: FloatArray | None = None
    if residual_gain > 0.0:
        total = residual_gain ** 2 * flow_covariance(prev, pts, residual, window_px)
    if image_noise_gray > 0.0:
        s = np.full(len(pts), image_noise_gray / GAUSSIAN_L1_TO_STD)
        c = flow_covariance(prev, pts, s, window_px)
        total = c if total is None else total + c
    if fb_gain > 0.0 and fb_error is not None:
        fb = np.asarray(fb_error, dtype=np.float64).reshape(-1)
        var = (fb_gain * np.where(np.isfinite(fb), fb, 0.0)) ** 2
        c = np.column_stack([var, np.zeros_like(var), var])
        total = c if total is None else total + c
    return total
