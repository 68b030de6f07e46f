"""The track's depth: how far ahead of the camera it is along the vehicle's x axis.

From the 3-D state while there is one; then carried on by the scale cue's expansion rate
(dZ/dt = -k Z), so that its time to contact can still be referred to the bumper and its
path judged, for ``MEMORY_S`` at most.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from appliance.decision.cues.base import CueInput

MEMORY_S = 3.0  # s, a depth carried on by the scale cue alone is forgotten after this


@dataclass(frozen=True)
class DepthState:
    """Depth (m, camera to object along the vehicle x axis) and when it last came from the
    3-D state (s)."""

    depth: float
    t: float


class Depth:
    name: ClassVar[str] = "depth"
    estimates_ground: ClassVar[bool] = False

    def update(self, prev: DepthState | None, x: CueInput, cfg: None) -> DepthState | None:
        f = x.frame
        g = x.ground
        if g is not None:
            return DepthState(depth=float(g.x[0] - f.mount.x_m), t=f.t)
        if prev is None:
            return None
        depth = prev.depth
        scale = x.now.get("scale")
        if scale is not None and scale.scale.n > 0:
            depth *= math.exp(-scale.scale.k * f.dt)
        if f.t - prev.t > MEMORY_S:
            return None
        return DepthState(depth=depth, t=prev.t)
