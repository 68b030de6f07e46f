"""How far up does a tracked object reach? Its flow, followed up the image from its box.

The particles gather where the evidence of independent motion is strongest; for a
pedestrian that is the feet: below the horizon the flow-length cue compares a pixel's
flow with the road's *behind* it, which is tight only at the foot point, and above the
horizon it needs a foot point close below (likelihood.foot_points). The track's box is
then a strip at the feet: right for the ground contact, wrong as the object's outline a
driver's display shows (a 60 px pedestrian reported as 8 px of shoes).

:func:`outline` measures it instead: Lucas-Kanade (current frame back to the
previous one, forward-backward checked) on a few columns across the box, row by row
upward from its top; a row belongs to the object while most of its measured flows agree
with the object's own (the median flow inside the box), within ``tolerance`` of its
length. It stops after ``max_gap`` rows that disagree, and at ``max_height_m`` above the
box bottom at the object's depth (no road user is taller). Rows where nothing could be
measured (flat clothing) neither extend nor stop it, up to ``MAX_UNMEASURED_M`` of them in a
row. Pure; the images come from the pipeline step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig
from appliance.decision.tracking import ImageTrack
from appliance.vision.flow import flow_into
from appliance.vision.geometry import FloatArray, PinholeCamera, in_image, lk_start

COLUMNS = 4          # probe columns across the box
MIN_TOLERANCE_PX = 0.5
MAX_UNMEASURED_M = 0.6   # more than this of rows without a flow in a row ends the outline


@dataclass(frozen=True)
class Outline:
    """What :func:`outline` found: the object's top row (px) and the flows it rests on,
    positions (M, 2) px in the current frame and flows (M, 2) px (current minus previous),
    of the points inside the box and in the rows that agreed (for the scale cue)."""

    top: float
    positions: FloatArray
    flows: FloatArray


def _none(v0: float) -> Outline:
    return Outline(top=v0, positions=np.zeros((0, 2)), flows=np.zeros((0, 2)))


def outline(prev: NDArray[np.uint8], cur: NDArray[np.uint8], box: tuple[float, float, float, float],
            depth_m: float, camera: PinholeCamera, flow_cfg: FlowConfig, expansion: float = 0.0,
            max_height_m: float = 2.0, tolerance: float = 0.3, max_gap: int = 2,
            rotation: FloatArray | None = None) -> Outline:
    """The object whose lower part is ``box`` (u0, v0, u1, v1) in ``cur``, at camera depth
    ``depth_m``: its top row, ``v0`` or higher (smaller), ``v0`` when its own flow cannot be
    measured in the box. ``expansion``: the object's image scale change per frame (about
    ``speed dt / depth`` when the camera drives at it): its flow at x is that at the box plus
    ``expansion (x - x_box)``, so the top of a pedestrian 2 m tall at 14 m moves ~1.7 px/frame
    more upward than its feet at 30 km/h. ``rotation`` (3, 3): the camera's rotation since
    ``prev`` (``X_cur = R X_prev + t``); LK starts where it alone moved each point (with
    ``flow_cfg.rotation_guess``) and the flows are compared without it, so that during a PTU
    pan (~15 px/frame) the tolerance is a share of the object's own motion, not of the pan's."""
    u0, v0, u1, v1 = box
    if not (depth_m > 0.0 and np.all(np.isfinite(box)) and u1 > u0 and v1 > v0):
        return _none(v0)
    step = max(2.0, 0.1 * camera.fy / depth_m)        # a row every 10 cm, at least 2 px
    v_min = max(0.0, v1 - max_height_m * camera.fy / depth_m)
    cols = np.linspace(u0, u1, COLUMNS + 2)[1:-1]
    inside_rows = np.linspace(v0, v1, 4)[1:-1]
    rows = np.arange(v0 - 0.5 * step, v_min, -step)
    if rows.size == 0:
        return _none(v0)
    grid_v = np.concatenate([inside_rows, rows])
    pts = np.column_stack([np.tile(cols, len(grid_v)), np.repeat(grid_v, len(cols))])
    ok_px = in_image(pts, camera.width, camera.height)
    probe = np.where(ok_px[:, None], pts, 0.0)
    origin = probe if rotation is None else lk_start(camera, probe, np.asarray(rotation).T)
    flow_px, valid_px = flow_into(prev, cur, probe, flow_cfg,
                                  origin if rotation is not None and flow_cfg.rotation_guess else None)
    grid = pts.reshape(len(grid_v), len(cols), 2)
    raw = flow_px.reshape(len(grid_v), len(cols), 2)
    flow = raw - (probe - origin).reshape(len(grid_v), len(cols), 2)   # the rotation's flow removed
    valid = (valid_px & ok_px).reshape(len(grid_v), len(cols))
    n_in = len(inside_rows)
    own = flow[:n_in][valid[:n_in]]
    if len(own) < 2:
        return _none(v0)
    f_obj = np.median(own, axis=0)
    x_obj = np.median(grid[:n_in][valid[:n_in]], axis=0)
    expected = f_obj + expansion * (grid - x_obj)
    tol = max(MIN_TOLERANCE_PX, tolerance * float(np.hypot(*f_obj)))
    max_blind = max(1, int(MAX_UNMEASURED_M * camera.fy / depth_m / step))
    agree = valid & (np.hypot(flow[..., 0] - expected[..., 0], flow[..., 1] - expected[..., 1]) <= tol)
    top, gap, blind, last = v0, 0, 0, n_in - 1
    for r in range(n_in, len(grid_v)):
        ok = valid[r]
        if ok.sum() < 2:                               # nothing measured: neither way, for a while
            blind += 1
            if blind > max_blind:
                break
            continue
        blind = 0
        if agree[r][ok].mean() >= 0.5:
            top, gap, last = grid_v[r] - 0.5 * step, 0, r
        else:
            gap += 1
            if gap >= max_gap:
                break
    use = agree[: last + 1]
    return Outline(top=float(max(top, v_min)), positions=grid[: last + 1][use],
                   flows=raw[: last + 1][use])


def extended(track_: ImageTrack, top: float) -> ImageTrack:
    """``track_`` with its box reaching up to row ``top`` (bottom and width kept)."""
    _, v0, _, v1 = track_.bbox
    if top >= v0:
        return track_
    x = track_.x.copy()
    x[1, 0] = 0.5 * (top + v1)
    return replace(track_, x=x, size=(track_.size[0], v1 - top))
