"""Ground truth of one frame: projected boxes, visible fractions, vehicle-frame states.

``bbox`` is the bounding box of the projected 3-D box (clipped at the near plane)
after clipping its silhouette to the image: ``[u0, v0, u1, v1]`` in pixels
(centres at integers, ``0 <= u <= width - 1``), i.e. the box of what the image shows.
``visible`` is the fraction of the box's silhouette inside the image that the
rendered id buffer shows as this object (1.0 = not occluded). An object is in
a frame's truth only when its box projects into the image.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import PinholeCamera

FloatArray = NDArray[np.float64]

# the 12 edges of a box whose corners are ordered as in world.Body.corners
_EDGES = [
    (0, 1),
    (1, 3),
    (3, 2),
    (2, 0),
    (4, 5),
    (5, 7),
    (7, 6),
    (6, 4),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
]


@dataclass(frozen=True)
class BoxView:
    """The projected box of one object: image points of its silhouette and its clipped bbox."""

    points: FloatArray  # (N, 2) silhouette (convex hull of the projected box) inside the image, px
    bbox: tuple[float, float, float, float]


def project_box(
    camera: PinholeCamera, camera_from_world: FloatArray, corners_w: FloatArray, near_m: float = 0.3
) -> BoxView | None:
    """Project 8 world corners (8, 3); None when the box is behind the camera or off the image."""
    Pc = corners_w @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
    z = Pc[:, 2]
    if np.all(z < near_m):
        return None
    front = z >= near_m
    if front.all():
        P = Pc
    else:
        pts = [Pc[front]]
        for a, b in _EDGES:
            if front[a] != front[b]:
                s = (near_m - z[a]) / (z[b] - z[a])
                pts.append((Pc[a] + s * (Pc[b] - Pc[a]))[None])
        P = np.concatenate(pts)
    if camera.has_distortion:
        uv = camera.project(P)
    else:
        uv = np.column_stack(
            [camera.fx * P[:, 0] / P[:, 2] + camera.cx, camera.fy * P[:, 1] / P[:, 2] + camera.cy]
        )
    W, H = camera.width - 1.0, camera.height - 1.0
    lo, hi = uv.min(0), uv.max(0)
    if hi[0] < 0 or hi[1] < 0 or lo[0] > W or lo[1] > H:
        return None
    hull = cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2).astype(np.float64)
    if lo[0] >= 0 and lo[1] >= 0 and hi[0] <= W and hi[1] <= H:
        return BoxView(hull, (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))
    inside = _clip_to_image(hull, W, H)
    if len(inside) < 3:
        return None
    u0, v0 = inside.min(0)
    u1, v1 = inside.max(0)
    return BoxView(inside, (float(u0), float(v0), float(u1), float(v1)))


def _clip_to_image(poly: FloatArray, umax: float, vmax: float) -> FloatArray:
    """The part of a convex polygon (N, 2) inside [0, umax] x [0, vmax] (Sutherland-Hodgman)."""
    pts = [tuple(p) for p in poly]
    for axis, bound, keep_below in (
        (0, 0.0, False),
        (0, umax, True),
        (1, 0.0, False),
        (1, vmax, True),
    ):
        out = []
        for i in range(len(pts)):
            a, b = pts[i], pts[(i + 1) % len(pts)]
            da = (bound - a[axis]) if keep_below else (a[axis] - bound)
            db = (bound - b[axis]) if keep_below else (b[axis] - bound)
            if da >= 0:
                out.append(a)
            if (da >= 0) != (db >= 0):
                s = da / (da - db)
                out.append((a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])))
        pts = out
        if not pts:
            break
    return np.array(pts, float).reshape(-1, 2)


def visible_fraction(view: BoxView, ids: NDArray[np.uint16], obj: int) -> float:
    """Fraction of the silhouette (convex hull of the projected box, inside the image) that
    the id buffer shows as ``obj``."""
    H, W = ids.shape
    x0, y0 = max(int(np.floor(view.bbox[0])), 0), max(int(np.floor(view.bbox[1])), 0)
    x1, y1 = int(np.ceil(view.bbox[2])) + 1, int(np.ceil(view.bbox[3])) + 1
    x1, y1 = min(x1, W), min(y1, H)
    if x1 <= x0 or y1 <= y0:
        return 0.0
    pts = np.rint((view.points - (x0, y0)) * 16).astype(np.int32)
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, 4)
    area = int(cv2.countNonZero(mask))
    if area == 0:
        return 0.0
    shown = int(np.count_nonzero((ids[y0:y1, x0:x1] == obj) & mask.view(bool)))
    return min(1.0, shown / area)


def boxes_near_image(
    camera: PinholeCamera,
    camera_from_world: FloatArray,
    corners_w: FloatArray,
    margin_px: float = 50.0,
) -> NDArray[np.bool_]:
    """Cheap pre-test for many boxes (N, 8, 3): which may project into the image (a superset)."""
    Pc = corners_w @ camera_from_world[:3, :3].T + camera_from_world[:3, 3]
    z = Pc[..., 2]
    zc = np.maximum(z, 0.3)
    u = camera.fx * Pc[..., 0] / zc + camera.cx
    v = camera.fy * Pc[..., 1] / zc + camera.cy
    m = margin_px
    out: NDArray[np.bool_] = (
        (z > 0.3).any(1)
        & (u.max(1) >= -m)
        & (u.min(1) <= camera.width + m)
        & (v.max(1) >= -m)
        & (v.min(1) <= camera.height + m)
    )
    return out


def truth_record(
    view: BoxView,
    ids: NDArray[np.uint16],
    obj: int,
    pos: FloatArray,
    vel: FloatArray,
    gap_m: float | None = None,
) -> dict[str, Any]:
    """One object's entry in a frame of ``truth.json`` (bbox px, visible, vehicle-frame m, m/s).

    ``pos_vehicle`` is the centre of the object's footprint; ``gap_m`` (written for movers, an
    addition to the spec's keys) is the distance between the footprint and the ego outline,
    what the appliance's ``distance_m`` estimates: for a car ahead it is half the car's length
    shorter than the gap to its centre, and 0 when they touch.
    """
    out = {
        "bbox": [round(float(b), 2) for b in view.bbox],
        "visible": round(visible_fraction(view, ids, obj), 3),
        "pos_vehicle": [round(float(pos[0]), 4), round(float(pos[1]), 4)],
        "vel_vehicle": [round(float(vel[0]), 4), round(float(vel[1]), 4)],
    }
    if gap_m is not None:
        out["gap_m"] = round(float(gap_m), 4)
    return out
