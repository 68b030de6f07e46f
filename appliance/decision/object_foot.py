"""Where does a tracked object meet the road? Its flow, followed down the image from its box.

The cluster's foot (its lowest moving particles) is the ground contact the 3-D state rests on.
Where the particles gather on a pedestrian's hips or knees rather than its feet (thin legs in
motion lose their flow to the forward-backward check), the contact sits above the feet and
reads too far: 13 px of legs below the cluster put a pedestrian 20 m ahead at 30 m, its range
then shrinks slower than the car drives, and it reads as walking away.

:func:`foot_probe` names the pixels on a few columns across and beside the box, row by row
downward from its bottom to where the road is a third as far; vision measures their flow
(current frame back to the previous one, forward-backward checked). Each flow is compared with
two predictions: the object's own (the median flow of its moving particles, with its
expansion) and the road's at that pixel (a road point there, moved by the camera's motion).
:func:`foot` walks down the rows, each flow weighed in its window's texture. A flow follows the
object where it follows neither the road nor a static surface nearer than it, and either the
object's own prediction lies apart from the road's or the flow itself lies ``APART`` std from
the road's (a swinging leg flows like neither the body nor the road). A row belongs to the
object where at least ``MIN_OBJECT`` flows follow it and at least half as many as follow the
road (between two legs the road shows), or ``MIN_OBJECT`` of them lie ``APART`` from the
road's; the object ends after ``max_gap`` rows in a row that do not. Rows where
the two predictions lie too close to tell apart (far away, or an object moving like the road),
where nothing was measured, or with a single flow apart from the road's, neither extend nor
stop it, up to ``MAX_BLIND`` of them in a row.
The object's bottom is put half a window above its last row (a window centred below an
object still holds some of it), unless at least ``MIN_OBJECT`` of its flows lie ``APART``
from both the road's and the body's: a limb swinging (a walker) or a wheel turning. Then its
lowest part on the road, a planted foot or a tyre's tread, stands still and flows like the
road, and the last row following the object is above it already.
Pure: decision never sees the images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.decision.ground_state import CameraPose, back_project
from appliance.vision.geometry import FloatArray, PinholeCamera, in_image

COLUMNS = 8          # probe columns across the box and a quarter of its width beside it,
MIN_SPAN_M = 0.6     #   over this much at the contact's depth at least
ROWS = 16            # probe rows between the box's bottom and the end of the search
MIN_STEP_PX = 1.5    # px between rows, at least
NEAREST_SHARE = 0.33  # the search ends where the road is this share of the contact's range
EDGE_PX = 6.0        # px, rows this close to the image's bottom are not probed
SEPARATION = 2.0     # flow std the two predictions must lie apart for a flow to say anything;
                     #   a flow follows the road within this many std
ROAD_SHARE = 0.1     # share of the road's flow added to a flow's std (road slope, body pitch)
TEXTURE_FLOOR = 30.0  # (gray levels / px)^2, a window's texture from which its flow is as good
                     #   as sigma_px: sensor noise alone gives about 1
MAX_BLIND = 4        # rows in a row that say nothing end the search
MIN_OBJECT = 2       # flows in a row that follow the object, at least, for it to belong to it
APART = 3.0          # flow std from the road's flow: a flow this far from it is not the road's,
                     #   whatever the object's own flow predicts (a swinging leg's is not the
                     #   body's)


@dataclass(frozen=True)
class FootProbe:
    """Where :func:`foot` reads the flow: ``points`` (K, 2) px of the current frame (outside
    the image: sent as (0, 0) and not used), ``grid`` (rows, COLUMNS, 2) the same by row,
    ``rows`` their image rows (downward from the box's bottom ``v1``), ``in_image`` (rows,
    COLUMNS), ``road`` (rows, COLUMNS, 2) px the flow a road point at each would have (current
    minus previous, the camera's rotation included), ``expansion`` (rows,) the scale change per
    frame of an object standing on the road at each row (the camera's approach over the road's
    depth there: were the object's feet at that row, its image would grow so), ``step`` px
    between rows, whether the image's bottom ``cut`` the search short, and the ``halo`` (px,
    half the Lucas-Kanade window): a window centred that far below the object's bottom still
    holds some of it, so the rows start that far below the box, and a row that follows the
    object puts its bottom that much above the row (and half a row below it)."""

    points: FloatArray
    grid: FloatArray
    rows: FloatArray
    in_image: NDArray[np.bool_]
    road: FloatArray
    expansion: FloatArray
    step: float
    v1: float
    cut: bool
    halo: float = 0.0


@dataclass(frozen=True)
class Foot:
    """What :func:`foot` found: the object's lowest row (px, an exclusive edge like a box's
    ``v1``), how many probe rows below the box followed the object, and whether it may reach
    the image's bottom (the search, cut short by the image, never saw the road below the
    object: the feet may be out of sight)."""

    bottom: float
    rows: int
    at_edge: bool = False


def road_points(camera: PinholeCamera, uv: FloatArray, pose: CameraPose) -> FloatArray:
    """The road points (N, 3) m, camera frame, seen at ``uv`` (N, 2) px; NaN above the
    horizon."""
    ground = back_project(camera, uv, pose)
    X = np.column_stack([ground, np.zeros(len(ground))]) - np.asarray(pose.position)
    return np.asarray(X @ pose.rotation())             # Rv^T X per row


def road_flow(camera: PinholeCamera, uv: FloatArray, pose: CameraPose,
              motion: tuple[FloatArray, FloatArray]) -> FloatArray:
    """The flow (N, 2) px, current minus previous, of road points seen at ``uv`` (N, 2) px in
    the current frame, for the camera motion ``(R, t)`` (``X_cur = R X_prev + t``, t in m);
    NaN above the horizon."""
    R, t = motion
    X_prev = (road_points(camera, uv, pose) - np.asarray(t)) @ np.asarray(R)  # R^T (X - t)
    return np.asarray(uv, dtype=np.float64) - camera.project(X_prev)


def foot_probe(box: tuple[float, float, float, float], camera: PinholeCamera, pose: CameraPose,
               motion: tuple[FloatArray, FloatArray], position: FloatArray | None = None,
               halo_px: float = 0.0) -> FootProbe | None:
    """The pixels whose flow :func:`foot` reads below ``box`` (u0, v0, u1, v1; ``v1`` the
    cluster's foot): ``COLUMNS`` columns over the box widened by a quarter of its width a side
    (``MIN_SPAN_M`` wide at least),
    ``ROWS`` rows from ``v1`` down to the row of the road at ``NEAREST_SHARE`` of the range at
    ``v1``; where ``v1`` is above the horizon (the particles on a head), of the range of
    ``position`` (2,) m, vehicle frame, the track's 3-D state. None without either, or when no
    row fits."""
    u0, v0, u1, v1 = box
    if not (np.all(np.isfinite(box)) and u1 > u0 and v1 > v0):
        return None
    uc = 0.5 * (u0 + u1)
    contact = back_project(camera, np.array([[uc, v1]]), pose)[0]
    if not np.all(np.isfinite(contact)):
        if position is None:
            return None
        contact = np.asarray(position, dtype=np.float64)
    cam = np.asarray(pose.position[:2])
    near = cam + NEAREST_SHARE * (contact - cam)
    X = (np.array([near[0], near[1], 0.0]) - np.asarray(pose.position)) @ pose.rotation()
    v_end = camera.project(X[None, :])[0, 1]
    cut = not (np.isfinite(v_end) and v_end <= camera.height - EDGE_PX)
    if cut:
        v_end = camera.height - EDGE_PX
    if v_end <= v1 + MIN_STEP_PX:
        return None
    step = max(MIN_STEP_PX, (v_end - v1) / ROWS)
    rows = np.arange(v1 + halo_px + 0.5 * step, v_end, step)
    if rows.size == 0:
        return None
    depth = float((np.array([contact[0], contact[1], 0.0]) - np.asarray(pose.position))
                  @ pose.rotation()[:, 2])
    half = 0.75 * (u1 - u0)
    if depth > 0.0:       # a sliver of an object (its edge) is probed across a pedestrian's width
        half = max(half, 0.5 * MIN_SPAN_M * camera.fx / depth)
    cols = np.linspace(uc - half, uc + half, COLUMNS)
    pts = np.column_stack([np.tile(cols, len(rows)), np.repeat(rows, len(cols))])
    ok = in_image(pts, camera.width, camera.height)
    road = road_flow(camera, pts, pose, motion)
    ok &= np.all(np.isfinite(road), axis=1)
    depth = road_points(camera, np.column_stack([np.full(len(rows), uc), rows]), pose)[:, 2]
    expansion = np.where(depth > 0.0, -float(np.asarray(motion[1])[2]) / depth, 0.0)
    return FootProbe(points=np.where(ok[:, None], pts, 0.0),
                     grid=pts.reshape(len(rows), len(cols), 2), rows=rows,
                     in_image=ok.reshape(len(rows), len(cols)),
                     road=np.where(ok[:, None], road, 0.0).reshape(len(rows), len(cols), 2),
                     expansion=np.nan_to_num(expansion), step=step, v1=v1, cut=cut,
                     halo=halo_px)


def flow_precision(tensor: FloatArray | None, n: int, sigma_px: float, extra_px: FloatArray
                   ) -> FloatArray:
    """Per point, the inverse (n, 2, 2) px^-2 of its flow's covariance: ``sigma_px`` along the
    best-textured direction of its window, more along a direction with less texture (the
    aperture problem: beside a horizontal edge the flow along the edge is not measured), by
    ``sqrt(max(l_max, TEXTURE_FLOOR) / l)`` for an eigenvalue l of its structure ``tensor``
    (n, 3) ``[gx gx, gx gy, gy gy]``; ``extra_px`` (n,) px added in every direction. Isotropic
    ``sigma_px`` without a tensor."""
    if tensor is None:
        var = np.full((n, 2), sigma_px ** 2)
        vecs = np.broadcast_to(np.eye(2), (n, 2, 2))
    else:
        t = np.asarray(tensor, dtype=np.float64).reshape(n, 3)
        M = np.stack([t[:, :2], t[:, 1:]], axis=1)
        lam, vecs = np.linalg.eigh(M)
        ref = np.maximum(lam[:, 1:], TEXTURE_FLOOR)
        var = sigma_px ** 2 * ref / np.maximum(lam, 1e-6)
    var = var + np.asarray(extra_px, dtype=np.float64)[:, None] ** 2
    return np.einsum("nij,nj,nkj->nik", vecs, 1.0 / var, vecs)


def mahalanobis(e: FloatArray, precision: FloatArray) -> FloatArray:
    """``sqrt(e^T P e)`` of vectors ``e`` (..., 2) under precisions ``P`` (..., 2, 2)."""
    return np.sqrt(np.maximum(np.einsum("...i,...ij,...j->...", e, precision, e), 0.0))


def foot(p: FootProbe | None, flow_px: FloatArray | None, valid_px: NDArray[np.bool_] | None,
         object_flow: FloatArray, object_at: FloatArray, sigma_px: float, max_gap: int = 2,
         tensor: FloatArray | None = None) -> Foot | None:
    """The object's lowest row below the probe's box (module docstring); None without a
    measurement.

    ``flow_px`` (K, 2), ``valid_px`` (K,): the flow measured at ``p.points``;
    ``object_flow`` (2,) px: the object's own flow (current minus previous, the rotation's
    included) at ``object_at`` (2,) px; at x in a probe row, an object reaching down to that
    row flows ``object_flow + e (x - object_at)``, e the row's ``p.expansion``; ``sigma_px``:
    a flow's std where its window is textured, ``tensor`` (K, 3): the windows' structure
    tensors (:func:`flow_precision`)."""
    if p is None or flow_px is None or valid_px is None:
        return None
    n_rows, n_cols = p.grid.shape[:2]
    flow = np.asarray(flow_px, dtype=np.float64).reshape(n_rows, n_cols, 2)
    valid = np.asarray(valid_px, dtype=bool).reshape(n_rows, n_cols) & p.in_image
    expected = np.asarray(object_flow) + p.expansion[:, None, None] * (
        p.grid - np.asarray(object_at))
    precision = flow_precision(tensor, n_rows * n_cols, sigma_px,
                               ROAD_SHARE * np.linalg.norm(p.road, axis=-1).ravel())
    precision = precision.reshape(n_rows, n_cols, 2, 2)
    excess = flow - p.road
    off_road = mahalanobis(excess, precision)      # std from the road's flow
    unit = p.road / np.maximum(np.linalg.norm(p.road, axis=-1), 1e-9)[..., None]
    along = np.sum(excess * unit, axis=-1)
    across = excess - along[..., None] * unit
    telling = valid & (mahalanobis(expected - p.road, precision) >= SEPARATION)
    follows_road = telling & (off_road <= SEPARATION)
    # longer than the road's along its direction: something static standing nearer
    static_nearer = (along > 0.0) & (mahalanobis(across, precision) <= SEPARATION)
    apart = valid & (off_road >= APART)
    follows_object = (telling | apart) & ~follows_road & ~static_nearer
    strong = follows_object & apart
    # apart from the body's flow too: a limb swinging (a walker), or a wheel turning
    swinging = strong & (mahalanobis(flow - expected, precision) >= APART)
    bottom, found, gap, blind, ended = p.v1, 0, 0, 0, False
    swings = 0
    for r in range(n_rows):
        n_obj, n_road = int(follows_object[r].sum()), int(follows_road[r].sum())
        n_strong = int(strong[r].sum())
        if n_obj >= MIN_OBJECT and (2 * n_obj >= n_road or n_strong >= MIN_OBJECT):
            bottom, found, gap, blind = float(p.rows[r] + 0.5 * p.step - p.halo), r + 1, 0, 0
            swings += int(swinging[r].sum())
        elif (n_road == 0 and n_obj < MIN_OBJECT) or n_strong > 0:
            blind += 1
            if blind > MAX_BLIND:    # the road not seen: where the object ends is not known
                break
        else:
            blind = 0
            gap += 1
            if gap >= max_gap:
                ended = True
                break
    if swings >= MIN_OBJECT:
        # the part on the road (a planted foot, a wheel's tread) is still: it flows like the
        # road, so the last row following the object is above it, not a halo below it
        bottom += p.halo
    return Foot(bottom=bottom, rows=found, at_edge=p.cut and found > 0 and not ended)


def lowered(box: tuple[float, float, float, float], bottom: float
            ) -> tuple[float, float, float, float]:
    """``box`` reaching down to row ``bottom`` (never raised)."""
    u0, v0, u1, v1 = box
    return (u0, v0, u1, max(v1, bottom))

