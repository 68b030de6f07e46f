"""Clustering of p(x) into moving objects (section 4 of the paper).

Threshold -> dilation -> connected-component labelling
(``cv2.connectedComponentsWithStats``, 8-connectivity) -> one :class:`Cluster`
per region with enough correspondences, carrying the paper's characterisation:
position, size, number of correspondences N, the weighted mean motion
(eq. 19) and the mean probability (eq. 20), taken over the correspondences
inside the object's box (``bbox``, below): the region's margin is the static
scene the blur spread the object's probability over, and beside a narrow object
(a pedestrian 20-30 m ahead) it would hold most of them.

Box of a cluster: the labelled region is the *blurred and dilated* probability,
so it is larger than the object by the Gaussian window and the dilation. The
box reported (``bbox``) therefore spans the region's correspondences whose own
particle weight is at least ``MEMBER_WEIGHT`` (the particles that actually
measured independent motion), shrunk by half the Lucas-Kanade window (the
particles' halo, :func:`shrink`); only when fewer than two such particles exist
is the region's box used. ``region_bbox`` keeps the region's box.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import ClusteringConfig
from appliance.messages import ParticleSet

FloatArray = NDArray[np.float64]
Box = tuple[float, float, float, float]

MEMBER_WEIGHT = 0.5   # a particle of a region with at least this weight spans the object's box


@dataclass(frozen=True)
class Cluster:
    """One region of independent motion in the current frame.

    bbox / region_bbox: (u0, v0, u1, v1), image px, u1/v1 exclusive-ish edges
    (u0 <= u < u1). n: number of correspondences N in the region.
    mean_flow: eq. 19, px/frame (du, dv). mean_probability: eq. 20, in [0, 1].
    positions (N, 2) px, flows (N, 2) px/frame, s (N,) the map probability at
    each correspondence and weights (N,) its own particle weight: the members,
    kept for the scale-change cue. foot_v: image row (px, exclusive edge like v1) of
    the object's lowest point, the particle extent less the halo even where the box
    is too small to shrink.
    """

    bbox: Box
    region_bbox: Box
    n: int
    foot_v: float
    mean_flow: tuple[float, float]
    mean_probability: float
    positions: FloatArray
    flows: FloatArray
    s: FloatArray
    weights: FloatArray

    @property
    def center(self) -> tuple[float, float]:
        """Centre of ``bbox`` (px)."""
        u0, v0, u1, v1 = self.bbox
        return (0.5 * (u0 + u1), 0.5 * (v0 + v1))


def weighted_mean_motion(flows: NDArray[np.floating], s: NDArray[np.floating]
                         ) -> tuple[float, float]:
    """Eq. 19: f_bar = sum(s_i f_i) / sum(s_i); flows (N, 2), s (N,). (0, 0) when sum(s) = 0."""
    f = np.asarray(flows, dtype=np.float64).reshape(-1, 2)
    w = np.asarray(s, dtype=np.float64).reshape(-1)
    total = float(np.sum(w))
    if total <= 0.0:
        return (0.0, 0.0)
    m = (w[:, None] * f).sum(axis=0) / total
    return (float(m[0]), float(m[1]))


def mean_probability(s: NDArray[np.floating]) -> float:
    """Eq. 20: q_bar = sum(s_i) / N; 0 for no correspondences."""
    w = np.asarray(s, dtype=np.float64).reshape(-1)
    return float(np.sum(w) / len(w)) if len(w) else 0.0


def object_probability(positions: NDArray[np.floating], s: NDArray[np.floating], box: Box
                       ) -> float:
    """Eq. 20 over the correspondences inside the object's box (``bbox``): the region around
    it is the blurred, dilated map, whose margin holds the static scene beside a narrow
    object; all of them where fewer than two lie inside."""
    u0, v0, u1, v1 = box
    pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    inside = (pos[:, 0] >= u0) & (pos[:, 0] < u1) & (pos[:, 1] >= v0) & (pos[:, 1] < v1)
    return mean_probability(np.asarray(s)[inside] if np.count_nonzero(inside) >= 2 else s)


def _box_of(points: FloatArray) -> Box:
    u0, v0 = points.min(axis=0)
    u1, v1 = points.max(axis=0)
    return (float(u0), float(v0), float(u1) + 1.0, float(v1) + 1.0)


def merge_clusters(parts: list[Cluster]) -> Cluster:
    """One cluster from several fragments of one object: members pooled, eqs. 19-20 redone
    over the pooled correspondences, boxes joined."""
    if len(parts) == 1:
        return parts[0]
    pos = np.vstack([c.positions for c in parts])
    flows = np.vstack([c.flows for c in parts])
    s = np.concatenate([c.s for c in parts])
    w = np.concatenate([c.weights for c in parts])

    def union(boxes: list[Box]) -> Box:
        b = np.array(boxes)
        return (float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()),
                float(b[:, 3].max()))

    box = union([c.bbox for c in parts])
    return Cluster(bbox=box, region_bbox=union([c.region_bbox for c in parts]), n=len(pos),
                   foot_v=max(c.foot_v for c in parts),
                   mean_flow=weighted_mean_motion(flows, s),
                   mean_probability=object_probability(pos, s, box),
                   positions=pos, flows=flows, s=s, weights=w)


def shrink(box: Box, halo_px: float, min_size: float = 2.0) -> Box:
    """The box shrunk by ``halo_px`` on every side (never below ``min_size``).

    A particle within half the Lucas-Kanade window of an object's edge measures
    part of the object's motion, so the cloud of high-weight particles reaches
    about half a window beyond the object (measured on rendered scenes: 4-5 px
    below the feet with an 11 px window).
    """
    u0, v0, u1, v1 = box
    du = min(halo_px, max((u1 - u0 - min_size) / 2.0, 0.0))
    dv = min(halo_px, max((v1 - v0 - min_size) / 2.0, 0.0))
    return (u0 + du, v0 + dv, u1 - du, v1 - dv)


def find_clusters(prob: NDArray[np.float32], scale: int, particles: ParticleSet,
                  cfg: ClusteringConfig, image_size: tuple[int, int], halo_px: float = 0.0
                  ) -> tuple[Cluster, ...]:
    """Regions of ``prob`` (map at 1/``scale``) above ``cfg.threshold``, as clusters.

    image_size: (width, height) px, to clip boxes. halo_px: the particle box is
    shrunk by this on each side (see :func:`shrink`). Ordered by region label
    (top-to-bottom, left-to-right scan), deterministic.
    """
    width, height = image_size
    binary = (prob >= cfg.threshold).astype(np.uint8)
    if not np.any(binary):
        return ()
    r = int(round(cfg.dilation_px / scale))
    if r > 0:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        binary = np.asarray(cv2.dilate(binary, kernel), dtype=np.uint8)
    n_labels, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if n_labels <= 1:
        return ()
    pos = np.asarray(particles.positions, dtype=np.float64).reshape(-1, 2)
    flow = np.asarray(particles.flow, dtype=np.float64).reshape(-1, 2)
    weight = np.asarray(particles.weights, dtype=np.float64).reshape(-1)
    ok = np.asarray(particles.valid, dtype=bool).reshape(-1)
    ok = ok & np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(flow), axis=1)
    ok &= np.isfinite(weight)
    rows, cols = prob.shape
    safe = np.where(np.isfinite(pos), pos, -1.0)
    col = np.floor(safe[:, 0] / scale).astype(np.int64)
    row = np.floor(safe[:, 1] / scale).astype(np.int64)
    ok &= (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    label_of = np.zeros(len(pos), dtype=np.int64)
    label_of[ok] = labels[row[ok], col[ok]]
    s_all = np.zeros(len(pos))
    s_all[ok] = prob[row[ok], col[ok]]
    clusters: list[Cluster] = []
    for lab in range(1, n_labels):
        members = label_of == lab
        n = int(np.count_nonzero(members))
        if n < cfg.min_correspondences:
            continue
        x0, y0, w, h = (int(v) for v in stats[lab, :4])
        region = (float(x0 * scale), float(y0 * scale),
                  float(min((x0 + w) * scale, width)), float(min((y0 + h) * scale, height)))
        mpos, mflow, ms, mw = pos[members], flow[members], s_all[members], weight[members]
        moving = mw >= MEMBER_WEIGHT
        if np.count_nonzero(moving) >= 2:
            extent = _box_of(mpos[moving])
            bbox = shrink(extent, halo_px)
            # the halo below the feet always comes off; from 20 particles on, the 99th
            # percentile (the sparse tail of road particles under an object is not the object)
            vs = mpos[moving, 1]
            low = float(np.percentile(vs, 99.0)) + 1.0 if len(vs) >= 20 else extent[3]
            foot = low - halo_px
        else:
            bbox = region
            foot = region[3]
        bbox = (max(bbox[0], 0.0), max(bbox[1], 0.0), min(bbox[2], float(width)),
                min(bbox[3], float(height)))
        clusters.append(Cluster(
            bbox=bbox, region_bbox=region, n=n, foot_v=min(foot, float(height)),
            mean_flow=weighted_mean_motion(mflow, ms),
            mean_probability=object_probability(mpos, ms, bbox),
            positions=mpos, flows=mflow, s=ms, weights=mw,
        ))
    return tuple(clusters)
