"""Where the track's object stands: its foot, below its cluster (``foot_search.py``).

The cluster of a pedestrian whose legs swing can end at the hips; the road below is the one
thing whose flow is known in advance, so the rows below the cluster whose flow is not the
road's are the object's. The foot row found replaces the cluster's bottom in the ground
contact (the ground cue); without one (the road starts right below the cluster, nothing
could be measured) the cluster's bottom stays the contact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from appliance.decision.cues.base import CueInput, Probe, TrackCues
from appliance.decision.foot_search import FootProbe, foot_probe, foot_row, road_flow
from appliance.decision.frame import BORDER_MARGIN_PX, FrameContext, border_sides
from appliance.decision.tracking import ImageTrack


@dataclass(frozen=True)
class FootState:
    """The object's foot row (px) found below its cluster this frame."""

    v: float


class Foot:
    name: ClassVar[str] = "foot"
    estimates_ground: ClassVar[bool] = False

    def probe(self, before: TrackCues | None, track: ImageTrack, f: FrameContext,
              cfg: None) -> Probe | None:
        c = track.cluster
        if not track.confirmed or c is None or not f.ego_known \
                or any(border_sides(c, f.camera, BORDER_MARGIN_PX, f.halo_px)):
            return None
        p = foot_probe(c.bbox, c.foot_v, f.camera, f.pose)
        return None if p is None else Probe(points=p.points, geometry=p)

    def update(self, prev: FootState | None, x: CueInput, cfg: None) -> FootState | None:
        if x.flow is None:
            return None
        probe, flow = x.flow
        p: FootProbe = probe.geometry
        f = x.frame
        t = np.asarray(f.ego.translation_dir, dtype=np.float64) * f.speed * f.dt
        road = road_flow(p.points, f.camera, f.pose, f.ego.rotation, t)
        v = foot_row(p, flow.flow, flow.valid, road, f.camera)
        return None if v is None else FootState(v=v)
