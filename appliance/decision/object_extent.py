"""How far up does a tracked object reach? Its flow, followed up the image from its box.

The particles gather where the evidence of independent motion is strongest; for a
pedestrian that is the feet: below the horizon the flow-length cue compares a pixel's
flow with the road's *behind* it, which is tight only at the foot point, and above the
horizon it needs a foot point close below (likelihood.foot_points). The track's box is
then a strip at the feet: right for the ground contact, wrong as the object's outline a
driver's display shows (a 60 px pedestrian reported as 8 px of shoes).

:func:`outline` measures it instead from the flow on a few columns across the box, row
by row upward from its top (:func:`outline_probe` names the pixels; vision measures them,
Lucas-Kanade from the current frame back to the previous one, forward-backward checked); a row belongs to the object while most of its measured flows agree
with the object's own (the median flow inside the box), within ``tolerance`` of its
length. It stops after ``max_gap`` rows that disagree, and at ``max_height_m`` above the
box bottom at the object's depth (no road user is taller). Rows where nothing could be
measured (flat clothing) neither extend nor stop it, up to ``MAX_UNMEASURED_M`` of them in a
row. Pure: decision never sees the images.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from appliance.decision.tracking import ImageTrack
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


@dataclass(frozen=True)
class OutlineProbe:
    """Where :func:`outline_probe` asks for the flow: ``points`` (K, 2) px of the current
    frame (a point outside the image is sent as (0, 0) and not used), ``grid`` (rows, COLUMNS,
    2) the same points by row (the rows inside the box first, ``inside`` of them, then upward
    from its top), ``rows`` their image rows, ``in_image`` (rows, COLUMNS), ``step`` px
    between rows, ``v_min`` the highest row, the box and the depth (m)."""

    points: FloatArray
    grid: FloatArray
    rows: FloatArray
    inside: int
    in_image: NDArray[np.bool_]
    step: float
    v_min: float
    box: tuple[float, float, float, float]
    depth_m: float


def outline_probe(box: tuple[float, float, float, float], depth_m: float, camera: PinholeCamera,
                  max_height_m: float = 2.0) -> OutlineProbe | None:
    """The pixels whose flow :func:`outline` reads for the object whose lower part is ``box``
    (u0, v0, u1, v1) at camera depth ``depth_m``: ``COLUMNS`` columns across the box, two rows
    inside it and a row every 10 cm (at least 2 px) upward from its top, up to ``max_height_m``
    above its bottom. None when the box or depth is unusable or no row fits (the outline is
    then the box)."""
    u0, v0, u1, v1 = box
    if not (depth_m > 0.0 and np.all(np.isfinite(box)) and u1 > u0 and v1 > v0):
        return None
    step = max(2.0, 0.1 * camera.fy / depth_m)        # a row every 10 cm, at least 2 px
    v_min = max(0.0, v1 - max_height_m * camera.fy / depth_m)
    cols = np.linspace(u0, u1, COLUMNS + 2)[1:-1]
    inside_rows = np.linspace(v0, v1, 4)[1:-1]
    rows = np.arange(v0 - 0.5 * step, v_min, -step)
    if rows.size == 0:
        return None
    grid_v = np.concatenate([inside_rows, rows])
    pts = np.column_stack([np.tile(cols, len(grid_v)), np.repeat(grid_v, len(cols))])
    ok_px = in_image(pts, camera.width, camera.height)
    probe = np.where(ok_px[:, None], pts, 0.0)
    return OutlineProbe(points=probe, grid=pts.reshape(len(grid_v), len(cols), 2), rows=grid_v,
                        inside=len(inside_rows), in_image=ok_px.reshape(len(grid_v), len(cols)),
                        step=step, v_min=v_min, box=box, depth_m=depth_m)


def outline(p: OutlineProbe | None, flow_px: FloatArray | None, valid_px: NDArray[np.bool_] | None,
            camera: PinholeCamera, rotation: FloatArray, expansion: float = 0.0,
            tolerance: float = 0.3, max_gap: int = 2) -> Outline | None:
    """The object whose lower part is the probe's box: its top row, ``v0`` or higher (smaller),
    ``v0`` when its own flow cannot be measured in the box; None without a measured flow
    (``flow_px`` None: the first frame).

    ``flow_px`` (K, 2), ``valid_px`` (K,): the flow measured at ``p.points`` (vision's
    ``probes.measure_points``), the camera rotation's flow included; ``rotation`` (3, 3): that
    rotation (``X_cur = R X_prev + t``), whose flow is removed so that during a PTU pan (~15
    px/frame) the tolerance is a share of the object's own motion, not of the pan's.
    ``expansion``: the object's image scale change per frame (about ``speed dt / depth`` when
    the camera drives at it): its flow at x is that at the box plus ``expansion (x - x_box)``,
    so the top of a pedestrian 2 m tall at 14 m moves ~1.7 px/frame more upward than its feet
    at 30 km/h."""
    if flow_px is None or valid_px is None:
        return None
    if p is None:
        return None
    v0 = p.box[1]
    origin = lk_start(camera, p.points, np.asarray(rotation).T)
    n_rows, n_cols = p.grid.shape[:2]
    grid = p.grid
    raw = np.asarray(flow_px, dtype=np.float64).reshape(n_rows, n_cols, 2)
    flow = raw - (p.points - origin).reshape(n_rows, n_cols, 2)   # the rotation's flow removed
    valid = np.asarray(valid_px, dtype=bool).reshape(n_rows, n_cols) & p.in_image
    n_in = p.inside
    own = flow[:n_in][valid[:n_in]]
    if len(own) < 2:
        return _none(v0)
    f_obj = np.median(own, axis=0)
    x_obj = np.median(grid[:n_in][valid[:n_in]], axis=0)
    expected = f_obj + expansion * (grid - x_obj)
    tol = max(MIN_TOLERANCE_PX, tolerance * float(np.hypot(*f_obj)))
    max_blind = max(1, int(MAX_UNMEASURED_M * camera.fy / p.depth_m / p.step))
    agree = valid & (np.hypot(flow[..., 0] - expected[..., 0], flow[..., 1] - expected[..., 1]) <= tol)
    top, gap, blind, last = v0, 0, 0, n_in - 1
    for r in range(n_in, n_rows):
        ok = valid[r]
        if ok.sum() < 2:                               # nothing measured: neither way, for a while
            blind += 1
            if blind > max_blind:
                break
            continue
        blind = 0
        if agree[r][ok].mean() >= 0.5:
            top, gap, last = p.rows[r] - 0.5 * p.step, 0, r
        else:
            gap += 1
            if gap >= max_gap:
                break
    use = agree[: last + 1]
    return Outline(top=float(max(top, p.v_min)), positions=grid[: last + 1][use],
                   flows=raw[: last + 1][use])


def extended(track_: ImageTrack, top: float, bottom: float | None = None) -> ImageTrack:
    """``track_`` with its box reaching up to row ``top`` and down to row ``bottom`` (width
    kept; a box is never cut)."""
    _, v0, _, v1 = track_.bbox
    lo = v1 if bottom is None else max(v1, bottom)
    hi = min(v0, top)
    if hi >= v0 and lo <= v1:
        return track_
    x = track_.x.copy()
    x[1, 0] = 0.5 * (hi + lo)
    return replace(track_, x=x, size=(track_.size[0], lo - hi))
