"""The flow at pixels the decision stage asks about.

Decision never sees images. Where it needs the flow at given pixels of the current frame
(how far up a tracked object reaches; whether something nearer covers a hidden one; whether
a hidden object's head keeps its bearing), it names the pixels, and :func:`measure_points`
measures them here: pyramidal Lucas-Kanade from the current frame back to the previous one,
forward-backward checked (:func:`flow.flow_into`), each point starting where the refined
camera rotation alone moved it (so a PTU pan of 15 px per frame stays within the pyramid's
reach). All requests of a frame share one pair of LK calls.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig
from appliance.vision.flow import flow_into
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix, lk_start

K = TypeVar("K", bound=Hashable)


@dataclass(frozen=True)
class PointFlow:
    """The measured flow (M, 2) px (current position minus previous) at each requested point,
    the rotation's flow included, and where it is valid (M,); ``tensor`` (M, 3), where
    measured: the mean structure tensor ``[gx gx, gx gy, gy gy]`` of each point's window in the
    current frame (gray levels^2 per px^2), which says in which direction its flow is known
    (along a line's direction it is not: the aperture problem)."""

    flow: FloatArray
    valid: NDArray[np.bool_]
    tensor: FloatArray | None = None


def structure_tensor(image: NDArray[np.uint8], points: FloatArray, window_px: int) -> FloatArray:
    """The mean structure tensor (M, 3) ``[gx gx, gx gy, gy gy]`` over the ``window_px`` square
    window at each of ``points`` (M, 2) px (nearest pixel; Scharr gradients / 32, so one
    gray level per px is 1; windows over the border are cut)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return np.zeros((0, 3))
    h, w = image.shape[:2]
    r = window_px // 2
    u = np.clip(np.rint(pts[:, 0]).astype(np.int64), 0, w - 1)
    v = np.clip(np.rint(pts[:, 1]).astype(np.int64), 0, h - 1)
    u0, u1 = max(int(u.min()) - r, 0), min(int(u.max()) + r + 1, w)
    v0, v1 = max(int(v.min()) - r, 0), min(int(v.max()) + r + 1, h)
    patch = np.asarray(image[v0:v1, u0:u1], dtype=np.float32)
    gx = cv2.Scharr(patch, cv2.CV_32F, 1, 0) / 32.0
    gy = cv2.Scharr(patch, cv2.CV_32F, 0, 1) / 32.0
    k = (window_px, window_px)
    comps = [cv2.boxFilter(a, -1, k, borderType=cv2.BORDER_REPLICATE)
             for a in (gx * gx, gx * gy, gy * gy)]
    return np.column_stack([c[v - v0, u - u0] for c in comps]).astype(np.float64)


def measure_from(prev: NDArray[np.uint8], cur: NDArray[np.uint8], points: FloatArray,
                 guess: FloatArray, cfg: FlowConfig) -> PointFlow:
    """The flow (current position minus the position in ``prev``) at ``points`` (M, 2) px of
    ``cur``, each search starting at ``guess`` (M, 2) px of ``prev``: for a probe over several
    frames, where a hypothesis says the point was (the rotation alone would not bring a point
    of the road there)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return PointFlow(np.zeros((0, 2)), np.zeros(0, dtype=bool))
    flow, valid = flow_into(prev, cur, pts, cfg, np.asarray(guess, dtype=np.float64))
    return PointFlow(flow, valid, structure_tensor(cur, pts, cfg.window_px))


def measure_points(prev: NDArray[np.uint8], cur: NDArray[np.uint8],
                   requests: Mapping[K, FloatArray], rotation: NDArray[np.floating],
                   camera: PinholeCamera, cfg: FlowConfig) -> dict[K, PointFlow]:
    """The flow at each request's points (M, 2) px of ``cur``, with their windows' structure
    tensors where measured (zeros elsewhere); ``rotation``: the refined camera rotation since ``prev`` (Euler angles, rad,
    ``X_cur = R X_prev + t``)."""
    keys = list(requests)
    pts = [np.asarray(requests[k], dtype=np.float64).reshape(-1, 2) for k in keys]
    out: dict[K, PointFlow] = {}
    sizes = [len(p) for p in pts]
    if sum(sizes) == 0:
        return {k: PointFlow(np.zeros((0, 2)), np.zeros(0, dtype=bool)) for k in keys}
    allpts = np.concatenate(pts)
    R = euler_to_matrix(np.asarray(rotation, dtype=np.float64))
    flow, valid = flow_into(prev, cur, allpts, cfg, lk_start(camera, allpts, R.T))
    start = 0
    for k, n, p in zip(keys, sizes, pts):
        ok = valid[start:start + n]
        tensor = np.zeros((n, 3))
        if np.any(ok):   # over the measured points only: a request's box stays its own
            tensor[ok] = structure_tensor(cur, p[ok], cfg.window_px)
        out[k] = PointFlow(flow[start:start + n], ok, tensor)
        start += n
    return out
