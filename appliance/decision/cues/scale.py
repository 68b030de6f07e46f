"""Time to contact from the growth of the track's image (``scale_ttc.py``).

Every frame the expansion of the track's outline flows (the whole object) is fitted, or of
its cluster's particles where the outline has too few points (for a pedestrian those are a
strip at its feet, for a lead car the row of its bumper, whose two edges step together); an
image border that cuts the box leaves that axis out. A scalar Kalman filter on the expansion
rate k = 1 / TTC smooths it; its TTC is used once it has ``min_frames`` measurements.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from appliance.config import ScaleCueConfig
from appliance.decision.clustering import MEMBER_WEIGHT
from appliance.decision.cues.base import CueInput
from appliance.decision.scale_ttc import (
    Expansion,
    ScaleState,
    measure_expansion,
    scale_predict,
    scale_ttc,
    scale_update,
)

PROCESS_STD = 0.3          # 1/s per sqrt(s), random walk of the expansion rate (closing speed changes)
OUTLINE_MIN_POINTS = 8     # outline flows the fit needs to prefer them to the cluster's particles


@dataclass(frozen=True)
class ScaleCueState:
    """The filtered expansion rate, this frame's measurement (None: none), whether the filter
    has the table's ``min_frames`` measurements (``trusted``), and then the time to contact
    with the image plane (s, std) if the object closes significantly (:func:`scale_ttc`)."""

    scale: ScaleState
    expansion: Expansion | None
    trusted: bool
    ttc: tuple[float, float] | None


class ScaleChange:
    name: ClassVar[str] = "scale"
    estimates_ground: ClassVar[bool] = False

    def update(self, prev: ScaleCueState | None, x: CueInput, cfg: ScaleCueConfig
               ) -> ScaleCueState | None:
        f = x.frame
        s = prev.scale if prev is not None else None
        if s is not None:
            s = scale_predict(s, f.dt, PROCESS_STD)
        m: Expansion | None = None
        c = x.track.cluster
        if c is not None and x.track.confirmed:
            left, right, bottom = x.meas.sides
            # a border cuts the box along one axis: what enters or leaves the image there is
            # no expansion, so the scale change is fitted along the other axis only
            axes = tuple(a for a, cut in ((0, left or right), (1, bottom)) if not cut)
            shape = x.now.get("outline")
            if shape is not None and len(shape.positions) >= OUTLINE_MIN_POINTS:
                m = measure_expansion(shape.positions, shape.flows, np.ones(len(shape.positions)),
                                      f.ego.rotation, f.camera, axes, f.window_px)
            if m is None:
                moving = c.weights >= MEMBER_WEIGHT
                m = measure_expansion(c.positions[moving], c.flows[moving], c.weights[moving],
                                      f.ego.rotation, f.camera, axes, f.window_px)
            if m is not None:
                s = scale_update(s, m, f.dt)
        if s is None:
            return None
        return ScaleCueState(scale=s, expansion=m, trusted=s.n >= cfg.min_frames,
                             ttc=scale_ttc(s, cfg.min_frames))
