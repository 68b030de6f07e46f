"""Kalman tracking of clusters in the image (section 4 of the paper, eqs. 21-24).

Each track carries two independent Kalman filters, one per image axis, on
``[position, velocity, acceleration]`` (eq. 21), measured by the cluster
position and its weighted mean flow (eqs. 22, 24); the process is the point
mass of eq. 23. Units: px and px per processed frame (the flow is measured
between consecutive processed frames, so one step is one time unit).

The list of filters is maintained by the paper's five rules, in order:

1. predict every filter;
2. each filter takes the region closest to its predicted position as its
   measurement if it is closer than ``gate_sigmas`` position std ("three times
   the Kalman filter variance") or closer than ``gate_px`` (7 px); otherwise no
   update;
3. a filter missing an update in any of its first ``confirm_frames`` steps after
   birth is removed; a filter not updated for ``max_missed`` steps is deleted;
4. a new filter is born for every region no filter took;
5. of two filters closer than ``merge_px`` the younger is deleted.

Before rule 2, regions whose centres fall inside a confirmed track's predicted
box are pooled into one region (``gather_fragments``): a near object breaks into
pieces that the paper's rules would otherwise turn into new filters.

A filter that survived its first ``confirm_frames`` steps is *confirmed* and
gets the next public id (stable for its life; ids of tentative filters that
die are never seen). The maths uses filterpy's ``predict``/``update`` free
functions, the same equations ``filterpy.kalman.KalmanFilter`` wraps, so a step
is a pure function of frozen state.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict, update
from numpy.typing import NDArray

from appliance.config import TrackingConfig
from appliance.decision.clustering import Cluster, merge_clusters

FloatArray = NDArray[np.float64]

# eq. 23 with one step as the time unit: x' = x + v + a/2, v' = v + a, a' = a
F_POINT_MASS: FloatArray = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
# eq. 24: the cluster position and mean flow measure x and v
H_POSITION_VELOCITY: FloatArray = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
BOX_SIZE_ALPHA = 0.5   # weight of the new cluster box size in a track's smoothed size


@dataclass(frozen=True)
class ImageModel:
    """The matrices of one axis' filter, built once from the configuration."""

    F: FloatArray
    H: FloatArray
    Q: FloatArray
    R: FloatArray
    P0: FloatArray

    @staticmethod
    def from_config(cfg: TrackingConfig) -> ImageModel:
        return ImageModel(
            F=F_POINT_MASS,
            H=H_POSITION_VELOCITY,
            Q=Q_discrete_white_noise(dim=3, dt=1.0, var=cfg.process_std_px ** 2),
            R=np.diag([cfg.position_std_px ** 2, cfg.velocity_std_px ** 2]),
            # the paper leaves acceleration out; it starts at 0 with the process std
            P0=np.diag([cfg.initial_position_std_px ** 2, cfg.initial_velocity_std_px ** 2,
                        cfg.process_std_px ** 2]),
        )


@dataclass(frozen=True)
class ImageTrack:
    """One cluster's two filters and bookkeeping.

    x: (2, 3) state ``[[u, v_u, a_u], [v, v_v, a_v]]`` (px, px/frame, px/frame^2);
    P: (2, 3, 3) covariances. size: smoothed box (width, height), px.
    uid: birth serial (smaller = older); id: public id once confirmed, else None.
    age: steps since birth; misses: consecutive steps without update.
    cluster: the region that updated it this step (None when it coasted).
    probability: eq. 20 of the regions that updated it, smoothed like the size.
    """

    uid: int
    id: int | None
    x: FloatArray
    P: FloatArray
    size: tuple[float, float]
    age: int
    misses: int
    cluster: Cluster | None
    probability: float

    @property
    def confirmed(self) -> bool:
        return self.id is not None

    @property
    def position(self) -> tuple[float, float]:
        return (float(self.x[0, 0]), float(self.x[1, 0]))

    @property
    def velocity(self) -> tuple[float, float]:
        return (float(self.x[0, 1]), float(self.x[1, 1]))

    @property
    def position_std(self) -> float:
        """Std of the position along the less certain axis, px."""
        return float(np.sqrt(max(self.P[0, 0, 0], self.P[1, 0, 0])))

    @property
    def bbox(self) -> tuple[float, float, float, float]:
        """Box (u0, v0, u1, v1) px around the filtered position with the smoothed size."""
        u, v = self.position
        w, h = self.size
        return (u - 0.5 * w, v - 0.5 * h, u + 0.5 * w, v + 0.5 * h)


@dataclass(frozen=True)
class TrackerState:
    tracks: tuple[ImageTrack, ...] = ()
    next_uid: int = 1
    next_id: int = 1


def _birth(cluster: Cluster, uid: int, model: ImageModel) -> ImageTrack:
    cu, cv = cluster.center
    x = np.array([[cu, cluster.mean_flow[0], 0.0], [cv, cluster.mean_flow[1], 0.0]])
    P = np.stack([model.P0, model.P0])
    u0, v0, u1, v1 = cluster.bbox
    return ImageTrack(uid=uid, id=None, x=x, P=P, size=(u1 - u0, v1 - v0), age=0, misses=0,
                      cluster=cluster, probability=cluster.mean_probability)


def _predict(track: ImageTrack, model: ImageModel) -> ImageTrack:
    xs, Ps = [], []
    for axis in range(2):
        x, P = predict(track.x[axis], track.P[axis], model.F, model.Q)
        xs.append(x)
        Ps.append(P)
    return replace(track, x=np.stack(xs), P=np.stack(Ps), age=track.age + 1, cluster=None)


def _update(track: ImageTrack, cluster: Cluster, model: ImageModel, alpha: float) -> ImageTrack:
    center = cluster.center
    xs, Ps = [], []
    for axis in range(2):
        z = np.array([center[axis], cluster.mean_flow[axis]])
        x, P = update(track.x[axis], track.P[axis], z, model.R, model.H)
        xs.append(x)
        Ps.append(P)
    u0, v0, u1, v1 = cluster.bbox
    w = (1.0 - alpha) * track.size[0] + alpha * (u1 - u0)
    h = (1.0 - alpha) * track.size[1] + alpha * (v1 - v0)
    q = (1.0 - alpha) * track.probability + alpha * cluster.mean_probability
    return replace(track, x=np.stack(xs), P=np.stack(Ps), size=(w, h), misses=0, cluster=cluster,
                   probability=q)


def gather_fragments(clusters: tuple[Cluster, ...], tracks: list[ImageTrack]
                     ) -> tuple[Cluster, ...]:
    """Regions whose centres lie inside one confirmed track's predicted box are one object.

    A near object spans many pixels with few particles, and its blurred
    probability can break into pieces; without this each piece would start a new
    filter (rule 4) whose "ground contact" is the middle of the object. Oldest
    track first; a region joins at most one track.
    """
    if len(clusters) < 2:
        return clusters
    taken = np.zeros(len(clusters), dtype=bool)
    centers = np.array([c.center for c in clusters])
    merged: list[Cluster] = []
    for t in sorted(tracks, key=lambda tr: tr.uid):
        if not t.confirmed:
            continue
        u0, v0, u1, v1 = t.bbox
        inside = ((centers[:, 0] >= u0) & (centers[:, 0] <= u1) & (centers[:, 1] >= v0)
                  & (centers[:, 1] <= v1) & ~taken)
        if np.count_nonzero(inside) >= 2:
            merged.append(merge_clusters([clusters[j] for j in np.flatnonzero(inside)]))
            taken |= inside
    return tuple(merged) + tuple(c for j, c in enumerate(clusters) if not taken[j])


def track_step(state: TrackerState, clusters: tuple[Cluster, ...], cfg: TrackingConfig,
               model: ImageModel | None = None) -> TrackerState:
    """One cycle of the five rules; returns the new list (oldest first)."""
    model = model or ImageModel.from_config(cfg)
    # rule 1: predict every filter
    tracks = [_predict(t, model) for t in state.tracks]
    clusters = gather_fragments(clusters, tracks)
    centers = np.array([c.center for c in clusters]).reshape(-1, 2)
    assigned = np.zeros(len(clusters), dtype=bool)
    # rule 2: closest region within the gate updates the filter
    for i, t in enumerate(tracks):
        if len(clusters):
            d = np.hypot(centers[:, 0] - t.x[0, 0], centers[:, 1] - t.x[1, 0])
            j = int(np.argmin(d))
            if d[j] < cfg.gate_px or d[j] < cfg.gate_sigmas * t.position_std:
                tracks[i] = _update(t, clusters[j], model, BOX_SIZE_ALPHA)
                assigned[j] = True
                continue
        tracks[i] = replace(t, misses=t.misses + 1)
    # rule 3: tentative filters must be updated in each of their first steps;
    # every filter dies after max_missed steps without an update
    kept = [t for t in tracks
            if t.misses < cfg.max_missed and not (t.id is None and t.misses > 0)]
    next_id = state.next_id
    for i, t in enumerate(kept):
        if t.id is None and t.age >= cfg.confirm_frames:
            kept[i] = replace(t, id=next_id)
            next_id += 1
    # rule 4: a new filter for every region no filter took
    next_uid = state.next_uid
    for j, c in enumerate(clusters):
        if not assigned[j]:
            kept.append(_birth(c, next_uid, model))
            next_uid += 1
    # rule 5: of two filters closer than merge_px the younger is deleted
    kept.sort(key=lambda t: t.uid)
    survivors: list[ImageTrack] = []
    for t in kept:
        if all(np.hypot(t.x[0, 0] - s.x[0, 0], t.x[1, 0] - s.x[1, 0]) >= cfg.merge_px
               for s in survivors):
            survivors.append(t)
    return TrackerState(tracks=tuple(survivors), next_uid=next_uid, next_id=next_id)
