"""Texture -> image homographies for the rasteriser: rip-map level choice and the warp.

For a planar face with texture frame (o, eu, ev) in camera coordinates and level-0 texel size
(su, sv) m, the level-0 texel (a, b) lies at ``X = o + a su eu + b sv ev`` and shows at pixel
``K X``: a homography. The level along each texture axis comes from the size of one image pixel
in texels there (the inverse Jacobian of that homography at the slab's centre). Warps use the
transparent border on a tiled (wrapping) or padded (stretched) source whenever the drawn polygon
fits it, which is about three times cheaper than the wrap or replicate borders.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.sim.polygons import Point, inverse3
from appliance.sim.textures import PAD, Texture


class FaceFrame(NamedTuple):
    """A face's texture frame in camera coordinates: origin and unit axes (m), texel size (m)."""

    o_c: list[float]
    eu_c: list[float]
    ev_c: list[float]
    texel: list[float]


def warp_texture(
    tex: Texture,
    face: FaceFrame,
    slab: Sequence[Point],
    roi_poly: list[list[float]],
    roi: tuple[int, int, int, int],
    k: tuple[float, float, float, float],
    lod_bias: float,
) -> NDArray[np.uint8]:
    """The face's texture warped into the ROI ``(x0, y0, w, h)`` at the level this slab needs.

    ``face``: the texture frame in camera coordinates; ``slab``: the slab polygon (camera frame,
    m); ``roi_poly`` (N, 2): the polygon drawn, in ROI pixels; ``k``: (fx, fy, cx, cy);
    level = floor(log2(texels per pixel) + lod_bias) along each texture axis.
    """
    x0, y0, w, h = roi
    su, sv = face.texel
    th, tw = tex.shape
    n = len(slab)
    C = [sum(c) / n for c in zip(*slab)]
    o = list(face.o_c)
    eu, ev = face.eu_c, face.ev_c
    rel = [C[k] - o[k] for k in range(3)]
    a = (rel[0] * eu[0] + rel[1] * eu[1] + rel[2] * eu[2]) / su
    b = (rel[0] * ev[0] + rel[1] * ev[1] + rel[2] * ev[2]) / sv
    if tex.wrap:  # shift the origin by whole periods so texture coordinates stay small
        ku, kv = math.floor(a / tw), math.floor(b / th)
        o = [o[k] + ku * tw * su * eu[k] + kv * th * sv * ev[k] for k in range(3)]
        a, b = a - ku * tw, b - kv * th
    fx, fy, cx, cy = k
    # camera-frame point of texel (a, b): X = o + a su eu + b sv ev; image = K X (homography H0)
    Xa = [su * eu[k] for k in range(3)]
    Xb = [sv * ev[k] for k in range(3)]
    X = [o[k] + a * Xa[k] + b * Xb[k] for k in range(3)]
    u, v = fx * X[0] / X[2] + cx, fy * X[1] / X[2] + cy
    # Jacobian d(u, v)/d(a, b) of the projection at the slab centre
    j00 = (fx * Xa[0] + cx * Xa[2] - u * Xa[2]) / X[2]
    j01 = (fx * Xb[0] + cx * Xb[2] - u * Xb[2]) / X[2]
    j10 = (fy * Xa[1] + cy * Xa[2] - v * Xa[2]) / X[2]
    j11 = (fy * Xb[1] + cy * Xb[2] - v * Xb[2]) / X[2]
    det = j00 * j11 - j01 * j10
    if abs(det) < 1e-12:
        ext_a = ext_b = 1e6
    else:  # extent of one pixel's footprint along each texture axis, texels
        ext_a = (abs(j11) + abs(j01)) / abs(det)
        ext_b = (abs(j10) + abs(j00)) / abs(det)
    mu, mv = tex.max_levels
    bias = lod_bias
    lu = min(max(int(math.floor(math.log2(max(ext_a, 1e-9)) + bias)), 0), mu)
    lv = min(max(int(math.floor(math.log2(max(ext_b, 1e-9)) + bias)), 0), mv)
    lev = tex.levels[lu][lv]
    hl, wl = lev.shape
    fu, fv = tw / wl, th / hl  # exact level scale factors
    ol = [o[k] + Xa[k] * (fu - 1.0) / 2.0 + Xb[k] * (fv - 1.0) / 2.0 for k in range(3)]
    c0 = [Xa[k] * fu for k in range(3)]
    c1 = [Xb[k] * fv for k in range(3)]
    H = [
        [
            fx * c0[0] + (cx - x0) * c0[2],
            fx * c1[0] + (cx - x0) * c1[2],
            fx * ol[0] + (cx - x0) * ol[2],
        ],
        [
            fy * c0[1] + (cy - y0) * c0[2],
            fy * c1[1] + (cy - y0) * c1[2],
            fy * ol[1] + (cy - y0) * ol[2],
        ],
        [c0[2], c1[2], ol[2]],
    ]
    # where the drawn polygon lies in level texels (mask pixels can stick out of it by about
    # a pixel: the margin), to use the fast transparent border on a tiled or padded source
    Hi = inverse3(H)
    al, bl = [], []
    for u, v in roi_poly:
        wq = Hi[2][0] * u + Hi[2][1] * v + Hi[2][2]
        al.append((Hi[0][0] * u + Hi[0][1] * v + Hi[0][2]) / wq)
        bl.append((Hi[1][0] * u + Hi[1][1] * v + Hi[1][2]) / wq)
    margin = 2.0 + 2.0 * max(ext_a / fu, ext_b / fv)
    src, border = lev, (cv2.BORDER_WRAP if tex.wrap else cv2.BORDER_REPLICATE)
    shift = None
    if tex.wrap:
        tiled, ku, kv = tex.source(lu, lv)
        sa = math.floor((min(al) - margin) / wl)
        sb = math.floor((min(bl) - margin) / hl)
        if max(al) - sa * wl + margin <= ku * wl - 1 and max(bl) - sb * hl + margin <= kv * hl - 1:
            src, border, shift = tiled, cv2.BORDER_TRANSPARENT, (sa * wl, sb * hl)
    elif margin <= PAD:
        src, border, shift = tex.source(lu, lv)[0], cv2.BORDER_TRANSPARENT, (-PAD, -PAD)
    if shift is not None:  # texel (0, 0) of src is level texel `shift`: H = H @ T(shift)
        for r in H:
            r[2] += r[0] * shift[0] + r[1] * shift[1]
    out = np.zeros((h, w), np.uint8)  # pixels a transparent border leaves lie off the mask
    cv2.warpPerspective(
        src, np.array(H), (w, h), dst=out, flags=cv2.INTER_LINEAR, borderMode=border
    )
    return np.asarray(out, np.uint8)
