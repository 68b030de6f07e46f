"""How far down the object reaches below its cluster: where it meets the road.

The ground contact is the cluster's foot; where the particles gather above the feet (on a
pedestrian's hips), the object's own flow continues below it, and the road's starts only at
its feet (``object_foot.py``). The pixels are planned from the track's cluster and the camera's
motion, and measured by vision; the ground cue then takes its contact at the lower of the two.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from appliance.decision.clustering import MEMBER_WEIGHT
from appliance.decision.cues.base import CueInput, Probe, TrackCues
from appliance.decision.frame import FrameContext, frame_motion
from appliance.decision.object_foot import Foot, FootProbe, foot, foot_probe
from appliance.decision.tracking import ImageTrack


class ObjectFoot:
    name: ClassVar[str] = "foot"
    estimates_ground: ClassVar[bool] = False

    def probe(self, before: TrackCues | None, track: ImageTrack, f: FrameContext,
              cfg: None) -> Probe | None:
        c = track.cluster
        if not track.confirmed or c is None:
            return None
        motion = frame_motion(f.ego, f.sensors, f.dt)
        if motion is None:
            return None
        u0, v0, u1, _ = c.bbox
        g = before.ground if before is not None else None
        p = foot_probe((u0, v0, u1, c.foot_v), f.camera, f.pose, motion,
                       None if g is None else g.position, f.halo_px)
        if p is None:
            return None
        return Probe(points=p.points, geometry=p)

    def update(self, prev: Foot | None, x: CueInput, cfg: None) -> Foot | None:
        c = x.track.cluster
        if x.flow is None or c is None:
            return None
        probe, flow = x.flow
        p = probe.geometry
        assert isinstance(p, FootProbe)
        moving = c.weights >= MEMBER_WEIGHT
        if np.count_nonzero(moving) < 2:
            return None
        return foot(p, flow.flow, flow.valid, np.median(c.flows[moving], axis=0),
                    np.median(c.positions[moving], axis=0), x.frame.flow_std_px,
                    tensor=flow.tensor)
