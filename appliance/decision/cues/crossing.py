"""The velocity across the line of sight from the track's sightings over a window.

At range the bearing is far more precise than the range from the ground contact (1 px of the
foot row is about 1.5 m at 40 m). Every frame with a fresh ground contact, a robust line
through the track's sightings of the last ``window_s`` (each ray cut at the range the 3-D
state had then, in an odometry frame so that ego turns are not motion;
``crossing_velocity.py``) updates the 3-D state's velocity across the line of sight.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from appliance.config import CrossingCueConfig
from appliance.decision.crossing_velocity import Sighting, windowed_crossing_update
from appliance.decision.cues.base import CueInput
from appliance.decision.ground_state import GroundTrack


@dataclass(frozen=True)
class CrossingState:
    """The sightings of the window, oldest first, and the 3-D state after the update."""

    sightings: tuple[Sighting, ...]
    ground: GroundTrack | None


class CrossingVelocity:
    name: ClassVar[str] = "crossing"
    estimates_ground: ClassVar[bool] = True

    def update(self, prev: CrossingState | None, x: CueInput, cfg: CrossingCueConfig
               ) -> CrossingState:
        f = x.frame
        window = cfg.window_s
        hist = prev.sightings if prev is not None else ()
        if x.meas.sighting is not None:
            hist = hist + (x.meas.sighting,)
        hist = tuple(h for h in hist if f.t - h[0] <= window)
        found = x.found.get(self.name) if x.found is not None else None
        if found is not None:
            hist = tuple(h for h in found.sightings + hist if f.t - h[0] <= window)
        g = x.ground
        if g is not None and g.t_update == f.t and g.updates > 1:
            g = windowed_crossing_update(g, hist, f.odo, (f.mount.x_m, f.mount.y_m))
        return CrossingState(sightings=hist, ground=g)
