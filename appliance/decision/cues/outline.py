"""How far up the object reaches above its cluster: the box a driver's display shows.

The particles of a pedestrian gather at its feet; its outline (``object_extent.py``) follows
its own flow up the image from the cluster's box, at most ``max_height_m`` above its ground
contact. The pixels are planned from the track's previous cues (its depth and how fast the
camera closes on it) and measured by vision; the outline's flows also feed the scale cue.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from appliance.config import OutlineCueConfig
from appliance.decision.cues.base import CueInput, Probe, TrackCues
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import (
    GroundModel,
    back_project,
    ground_in_camera,
    road_axis,
)
from appliance.decision.object_extent import Outline, outline, outline_probe
from appliance.decision.tracking import ImageTrack
from appliance.vision.geometry import euler_to_matrix

TOLERANCE = 0.25   # a flow agrees with the object's (its expansion included) within this share of its length
MIN_DEPTH_M = 0.5  # m, nearer than this no outline is measured


def outline_depth(tr: ImageTrack, before: TrackCues | None, f: FrameContext) -> float | None:
    """Camera depth (m) at which a track's outline is measured: its 3-D state's (last
    frame's) or, without one, the road's under the bottom of its cluster. An object further
    than the ground cue's range (a cyclist at 70 m) has no 3-D state, but the outline needs
    its depth only roughly (how many pixels 2 m are there), not as a measurement of its
    position. None above the horizon, nearer than 0.5 m, or with neither."""
    g = before.ground if before is not None else None
    if g is not None:
        foot = ground_in_camera(f.pose, g.position)
    elif tr.cluster is not None:
        u0, _, u1, _ = tr.cluster.bbox
        road = back_project(f.camera, np.array([[0.5 * (u0 + u1), tr.cluster.foot_v - 0.5]]),
                            f.pose)[0]
        if not np.all(np.isfinite(road)):
            return None
        foot = ground_in_camera(f.pose, road)
    else:
        return None
    return float(foot[2]) if foot[2] > MIN_DEPTH_M else None


def closing_step(before: TrackCues | None, f: FrameContext) -> float:
    """How far (m) the camera closes on the track's object along its optical axis in one
    frame: the ego vehicle's travel less the object's own along the axis (its 3-D state's
    velocity over ground) for an object moving over ground at a vehicle's speed
    (``GroundModel.accel_min_speed_m_s``) or faster; the ego vehicle's travel alone for a
    slower one or one without a 3-D state (as if static).

    The object's image grows by this over its depth per frame: a pedestrian crossing ahead at
    30 km/h expands by 0.02 per frame at 14 m, a lead car at the ego's speed not at all. A
    pedestrian's velocity along the axis is the least certain part of its 3-D state (+2 m/s
    off at 35 m): for slow objects the static assumption is the better one.
    """
    g = before.ground if before is not None else None
    d = road_axis(f.pose)
    if g is None or d is None or g.speed < GroundModel.accel_min_speed_m_s:
        return f.speed * f.dt
    return float(f.speed * d[0] - d @ g.velocity) * f.dt


class ObjectOutline:
    name: ClassVar[str] = "outline"
    estimates_ground: ClassVar[bool] = False

    def probe(self, before: TrackCues | None, track: ImageTrack, f: FrameContext,
              cfg: OutlineCueConfig) -> Probe | None:
        if not track.confirmed:
            return None
        depth = outline_depth(track, before, f)
        if depth is None:
            return None
        p = outline_probe(track.bbox, depth, f.camera, cfg.max_height_m)
        expansion = closing_step(before, f) / depth
        return Probe(points=np.zeros((0, 2)) if p is None else p.points, geometry=(p, expansion))

    def update(self, prev: Outline | None, x: CueInput, cfg: OutlineCueConfig) -> Outline | None:
        if x.flow is None:
            return None
        probe, flow = x.flow
        p, expansion = probe.geometry
        return outline(p, flow.flow, flow.valid, x.frame.camera,
                       euler_to_matrix(x.frame.ego.rotation), expansion, TOLERANCE)
