"""The per-track cues, in the order they run (``base.py`` says what a cue is).

To add a cue: write its module here (its state, and a class with ``name``,
``estimates_ground`` and ``update``), add it to ``CUES`` where what it reads has run, and give
it a table ``[cue.<name>]`` in ``config/default.toml`` with its dataclass in
``appliance/config.py`` (``CueConfig``) if it has parameters a user would change. To remove
one, undo the same. Nothing else refers to a cue except through its state's name, and every
reader treats a missing state as "no opinion".
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from appliance.config import CueConfig
from appliance.decision.cues.base import Cue, CueInput, Probe, ProbingCue, TrackCues
from appliance.decision.cues.bearing import Bearing
from appliance.decision.cues.crossing import CrossingVelocity
from appliance.decision.cues.depth import Depth
from appliance.decision.cues.foot import ObjectFoot
from appliance.decision.cues.ground import GroundContact
from appliance.decision.cues.motion import Motion
from appliance.decision.cues.outline import ObjectOutline
from appliance.decision.cues.peaks import Peaks
from appliance.decision.cues.range_rate import RangeRate
from appliance.decision.cues.scale import ScaleChange
from appliance.decision.frame import FrameContext
from appliance.decision.tracking import ImageTrack
from appliance.vision.probes import PointFlow

__all__ = ["CUES", "Cue", "CueInput", "Probe", "TrackCues", "probes", "update_cues"]

CUES: tuple[Cue, ...] = (
    Bearing(),           # bearing history and rate
    ObjectOutline(),     # how far up the object reaches (flow measured by vision)
    ObjectFoot(),        # how far down: where it meets the road (flow measured by vision)
    GroundContact(),     # the 3-D state from the ground contact
    CrossingVelocity(),  # its velocity across the line of sight, from the sightings
    ScaleChange(),       # time to contact from the image's growth
    RangeRate(),         # its velocity along the camera axis, from the growth
    Depth(),             # depth, carried on by the growth without a 3-D state
    Motion(),            # has it moved over the ground?
    Peaks(),             # the most it has shown of itself
)


def table(cfg: CueConfig, cue: Cue) -> Any:
    """The cue's table ``[cue.<name>]``, None when it has none."""
    return getattr(cfg, cue.name, None)


def probes(before: TrackCues | None, track: ImageTrack, frame: FrameContext, cfg: CueConfig
           ) -> Iterable[tuple[str, Probe]]:
    """(cue name, probe) of every cue that asks vision for the flow at some pixels this frame."""
    for cue in CUES:
        if isinstance(cue, ProbingCue):
            p = cue.probe(before, track, frame, table(cfg, cue))
            if p is not None:
                yield cue.name, p


def update_cues(before: TrackCues | None, x: CueInput, cfg: CueConfig,
                flows: dict[str, tuple[Probe, PointFlow]]) -> TrackCues:
    """Every cue of ``CUES`` in order: the track's cues after this frame. ``x`` carries the
    frame's measurements of the track (and the hidden track it continues); ``flows``: what vision
    measured at each cue's probe."""
    ground = before.ground if before is not None else None
    now: dict[str, Any] = {}
    for cue in CUES:
        prev = before.get(cue.name) if before is not None else None
        xi = CueInput(track=x.track, meas=x.meas, frame=x.frame, ground=ground, now=now,
                      found=x.found, flow=flows.get(cue.name))
        state = cue.update(prev, xi, table(cfg, cue))
        if state is not None:
            now[cue.name] = state
        if cue.estimates_ground:
            ground = state.ground if state is not None else None
    return TrackCues(ground=ground, states=now)
