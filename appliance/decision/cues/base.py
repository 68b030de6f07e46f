"""The interface of a per-track cue, and what it is given.

A cue estimates one thing about a track, every frame: its bearing history, its 3-D state on
the road, its image's growth, whether it has moved over the ground... It is a small object with

* ``name``: the key of its state in :class:`TrackCues` and of its table ``[cue.<name>]`` in the
  configuration (a cue without parameters a user would change has no table);
* ``estimates_ground``: whether its state carries the track's 3-D state (``state.ground``),
  which the cues after it then see as ``x.ground``;
* ``update(prev, x, cfg) -> state``: its state of the previous frame (None for a new track),
  what this frame measured of the track (:class:`CueInput`) and its table; it returns its new
  state (frozen), or None when it has nothing to say.

A cue may also ask vision to measure the flow at some pixels of the current frame
(``probe``, see :class:`Probe`); the flow comes back to its ``update`` as ``x.flow``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

from appliance.decision.frame import FrameContext, TrackMeasurement
from appliance.decision.ground_state import GroundTrack
from appliance.decision.tracking import ImageTrack
from appliance.vision.geometry import FloatArray
from appliance.vision.probes import PointFlow


@dataclass(frozen=True)
class TrackCues:
    """A track's cues after a frame: its 3-D state as the last cue that estimates it left it,
    and every cue's own state by name (a cue that said nothing is absent)."""

    ground: GroundTrack | None = None
    states: Mapping[str, Any] = field(default_factory=dict)

    def get(self, name: str) -> Any:
        """The state of cue ``name``, None when it has none."""
        return self.states.get(name)

    def replaced(self, **states: Any) -> TrackCues:
        """A copy with the states of the named cues replaced (None: removed)."""
        merged = {k: v for k, v in {**self.states, **states}.items() if v is not None}
        return TrackCues(ground=self.ground, states=merged)


@dataclass(frozen=True)
class Probe:
    """Pixels (M, 2) of the current frame whose flow a cue needs (``points``), and what the
    cue needs to read them (``geometry``, the cue's own type)."""

    points: FloatArray
    geometry: Any


@dataclass(frozen=True)
class CueInput:
    """What a cue is given for one track in one frame.

    track: the image track (its cluster, box, probability); meas: the frame's geometry of it
    (contact, bearing, sighting); frame: what the frame's computations share; ground: the 3-D
    state as the cues before this one left it (the previous frame's at first); now: the states
    the cues before this one returned this frame; found: the cues of the hidden (lost) track
    this new track continues, if any (its first ground contact fell in that track's gate);
    flow: the flow vision measured at this cue's probe, with the probe, if it asked."""

    track: ImageTrack
    meas: TrackMeasurement
    frame: FrameContext
    ground: GroundTrack | None = None
    now: Mapping[str, Any] = field(default_factory=dict)
    found: TrackCues | None = None
    flow: tuple[Probe, PointFlow] | None = None


class Cue(Protocol):
    name: ClassVar[str]
    estimates_ground: ClassVar[bool]

    def update(self, prev: Any, x: CueInput, cfg: Any) -> Any:
        """The cue's new state for this frame."""
        ...


@runtime_checkable
class ProbingCue(Cue, Protocol):
    def probe(self, before: TrackCues | None, track: ImageTrack, frame: FrameContext,
              cfg: Any) -> Probe | None:
        """The pixels whose flow this cue needs this frame, planned from the track's cues of
        the previous frame (``before``); None: none."""
        ...
