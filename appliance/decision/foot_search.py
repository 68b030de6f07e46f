"""Where a tracked object stands: its foot, found below its cluster from the road's flow.

A cluster covers where the evidence of independent motion is strongest. For a pedestrian
whose legs swing, the forward-backward check drops most of the legs' flows, and the cluster
can end at the hips or knees: its bottom, back-projected onto the road, is then metres too
far (14.5 m for a pedestrian at 9.7 m), and everything that rests on the ground contact
(range, velocity over ground, whether it moves at all) inherits the error.

Below the object is the road, the one thing whose flow is known in advance: with the refined
camera motion, the CAN speed and the camera's pose over the road plane, a road point seen at
pixel x came from a known place (plane + parallax). :func:`foot_probe` names columns of
pixels from the cluster's bottom down; :func:`foot_row` reads the flows vision measured there,
row by row. A row belongs to the object while some of its measured flows (a leg is thin)
differ from the road's there; two rows of road in a row end it. Rows without a verdict (the
legs' flows fail the forward-backward check, flat trousers) neither extend nor end it, for a
while. The search reaches down to where the cluster's bottom would be
``MAX_CLUSTER_HEIGHT_M`` above the road: no part of a road user left out below its cluster
is taller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.decision.ground_state import CameraPose
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix, in_image

COLUMNS = 7                  # probe columns across the object's width
MIN_WIDTH_M = 0.8            # m, a road user's width at least searched (a stride; a cluster can be a strip)
MAX_CLUSTER_HEIGHT_M = 1.0   # m, the highest a cluster's bottom can sit above the object's foot
MAX_ROWS = 40                # probe rows at most (the step grows for a long search)
MIN_STEP_PX = 2.0            # px between probe rows at least
MIN_TOLERANCE_PX = 2.0       # px, a road point's flow is within this of the road's (3 std of LK on blurred, noisy road)
TOLERANCE = 0.25             # or within this share of the road's flow (speed, pitch, slope errors)
CLEAR_OFF = 2.0              # a single flow this many tolerances off the road's makes a row the object's
ROAD_ROWS_END = 2            # road rows in a row that end the object
MAX_BLIND_M = 0.4            # m of rows without a verdict in a row that end the search
MIN_DROP = 1e-6              # a ray must point this much below the horizon to meet the road


@dataclass(frozen=True)
class FootProbe:
    """Where :func:`foot_probe` asks for the flow: ``points`` (rows * COLUMNS, 2) px of the
    current frame, the same as ``grid`` (rows, COLUMNS, 2), ``rows`` their image rows (top
    down), ``step`` px between rows, the cluster's bottom row ``v_bottom``, and how many rows
    without a verdict in a row end the search (``max_blind``, ``MAX_BLIND_M``)."""

    points: FloatArray
    grid: FloatArray
    rows: FloatArray
    step: float
    v_bottom: float
    max_blind: int


def road_normal(pose: CameraPose) -> FloatArray:
    """The road's upward normal (3,) in the camera frame."""
    return np.asarray(pose.rotation().T @ np.array([0.0, 0.0, 1.0]))


def foot_probe(box: tuple[float, float, float, float], v_bottom: float, camera: PinholeCamera,
               pose: CameraPose) -> FootProbe | None:
    """The pixels below a cluster (its box ``(u0, v0, u1, v1)``, its bottom row ``v_bottom``)
    whose flow :func:`foot_row` reads: ``COLUMNS`` columns across the box (at least
    ``MIN_WIDTH_M`` wide at the road's depth under its bottom), rows
    from just below ``v_bottom`` down to where ``v_bottom`` would be ``MAX_CLUSTER_HEIGHT_M``
    above the object's foot (or the image's bottom). None when the cluster's bottom is not
    below the horizon or no row fits."""
    u0, _, u1, _ = box
    if not (np.all(np.isfinite(box)) and u1 >= u0 and np.isfinite(v_bottom)):
        return None
    uc = 0.5 * (u0 + u1)
    n = road_normal(pose)
    height = float(pose.position[2])
    if height <= MAX_CLUSTER_HEIGHT_M:
        return None
    # a point at depth Z on the ray r is h + Z (n . r) above the road: the object's foot, at
    # the depth of a cluster bottom h_c above it, is seen where n . r = (n . r_c) H / (H - h_c)
    column = np.arange(np.ceil(v_bottom), camera.height, dtype=np.float64)
    if column.size == 0:
        return None
    drops = camera.rays(np.column_stack([np.full(column.size, uc), column])) @ n
    d0 = float(camera.rays(np.array([[uc, v_bottom]]))[0] @ n)
    if d0 >= -MIN_DROP:
        return None
    lowest = d0 * height / (height - MAX_CLUSTER_HEIGHT_M)
    reach = column[drops >= lowest]
    v_max = float(reach[-1]) if reach.size else float(v_bottom)
    if v_max <= v_bottom + MIN_STEP_PX:
        return None
    step = max(MIN_STEP_PX, (v_max - v_bottom) / MAX_ROWS)
    rows = np.arange(v_bottom + 0.5 * step, v_max, step)
    # as wide as the box, and at least MIN_WIDTH_M at the depth of the road under the cluster's
    # bottom (the object is nearer: wider in the image)
    half = 0.5 * max(u1 - u0, MIN_WIDTH_M * camera.fx * -d0 / height)
    cols = np.linspace(uc - half, uc + half, COLUMNS)
    grid = np.stack(np.meshgrid(cols, rows), axis=-1)          # (rows, COLUMNS, 2)
    max_blind = max(2, int(np.ceil(MAX_BLIND_M * camera.fy * -d0 / height / step)))
    return FootProbe(points=grid.reshape(-1, 2), grid=grid, rows=rows, step=step,
                     v_bottom=float(v_bottom), max_blind=max_blind)


def road_flow(uv: NDArray[np.floating], camera: PinholeCamera, pose: CameraPose,
              rotation: NDArray[np.floating], translation_m: NDArray[np.floating]) -> FloatArray:
    """The flow (N, 2) px (current minus previous position) of road points seen at pixels
    ``uv`` (N, 2) of the current frame, for the camera motion ``X_cur = R X_prev + t``
    (``rotation``: Euler angles, rad; ``translation_m``: t, m); NaN where the pixel does not
    see the road (at or above the horizon)."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    rays = camera.rays(uv)
    drop = rays @ road_normal(pose)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(drop < -MIN_DROP, -float(pose.position[2]) / drop, np.nan)
    X_cur = rays * lam[:, None]
    R = euler_to_matrix(np.asarray(rotation, dtype=np.float64))
    X_prev = (X_cur - np.asarray(translation_m, dtype=np.float64)) @ R    # R^T (X_cur - t)
    return uv - camera.project(X_prev)


def foot_row(p: FootProbe, flow_px: FloatArray, valid_px: NDArray[np.bool_],
             road_px: FloatArray, camera: PinholeCamera) -> float | None:
    """The object's foot row (px) below the cluster, None when the road starts right below it
    (or nothing could be read).

    ``flow_px`` (K, 2), ``valid_px`` (K,): the flow vision measured at ``p.points``;
    ``road_px`` (K, 2): the road's flow there (:func:`road_flow`). A measured flow is the
    road's when within ``max(MIN_TOLERANCE_PX, TOLERANCE |road flow|)`` of it. Scanning down
    from the cluster's bottom, a row with two measured flows off the road's, or one clearly off
    (``CLEAR_OFF`` tolerances: a leg is a column of a stride, beside it the road), is the
    object's; a row with two or more flows all the road's is road; any other row has no verdict (the legs' flows often fail the
    forward-backward check). ``ROAD_ROWS_END`` road
    rows in a row end the object, as do ``p.max_blind`` rows without a verdict. The foot is the
    bottom of the last object row.
    """
    n_rows = len(p.rows)
    shape = (n_rows, -1)
    flow = np.asarray(flow_px, dtype=np.float64).reshape(n_rows, -1, 2)
    road = np.asarray(road_px, dtype=np.float64).reshape(n_rows, -1, 2)
    ok = (np.asarray(valid_px, dtype=bool).reshape(shape)
          & in_image(p.points, camera.width, camera.height).reshape(shape)
          & np.all(np.isfinite(road), axis=-1))
    miss = np.hypot(*(flow - road).transpose(2, 0, 1))
    tol = np.maximum(MIN_TOLERANCE_PX, TOLERANCE * np.hypot(*road.transpose(2, 0, 1)))
    off = ok & (miss > tol)
    on = ok & ~(miss > tol)
    clear = ok & (miss > CLEAR_OFF * tol)
    last: int | None = None
    road_run = blind = 0
    for r in range(n_rows):
        n_off, n_on = int(off[r].sum()), int(on[r].sum())
        if n_off >= 2 or clear[r].any():
            last, road_run, blind = r, 0, 0
        elif n_off == 0 and n_on >= 2:
            road_run, blind = road_run + 1, 0
            if road_run >= ROAD_ROWS_END:
                break
        else:
            blind += 1
            if blind >= p.max_blind:
                break
    if last is None:
        return None
    return float(min(p.rows[last] + 0.5 * p.step, camera.height))
