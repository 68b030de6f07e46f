"""The 3-D state's velocity along the camera axis, from the track's image growth.

An object at depth Z closing at c expands at c / Z: with the scale cue's expansion rate of
this frame and the 3-D state's own depth, its velocity over ground along the camera axis is
the ego's speed less rate x Z (``ground_state.range_rate_update``). Applied every frame with a
fresh ground contact once the scale cue is trusted; each rate counts with ``std_gain`` times
its fit's std, and one further than the 3-D filter's gate from the state's own is skipped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from appliance.config import RangeRateCueConfig
from appliance.decision.cues.base import CueInput
from appliance.decision.ground_state import GroundModel, GroundTrack, range_rate_update


@dataclass(frozen=True)
class RangeRateState:
    """The 3-D state after the update."""

    ground: GroundTrack | None


class RangeRate:
    name: ClassVar[str] = "range_rate"
    estimates_ground: ClassVar[bool] = True

    def update(self, prev: RangeRateState | None, x: CueInput, cfg: RangeRateCueConfig
               ) -> RangeRateState:
        f = x.frame
        g = x.ground
        scale = x.now.get("scale")
        m = scale.expansion if scale is not None else None
        if scale is not None and m is not None and g is not None and g.t_update == f.t \
                and f.dt > 0.0 and m.kappa > -0.9 and scale.trusted:
            var = m.var / ((1.0 + m.kappa) * f.dt) ** 2 * cfg.std_gain ** 2
            g = range_rate_update(g, math.log1p(m.kappa) / f.dt, var, f.pose, f.speed,
                                  GroundModel.gate_sigmas)
        return RangeRateState(ground=g)
