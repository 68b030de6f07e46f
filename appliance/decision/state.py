"""What the decision stage carries from frame to frame, and what it hands on (frozen)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from appliance.decision.clustering import Cluster
from appliance.decision.cues import Probe, TrackCues
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import CameraPose
from appliance.decision.halted import HaltProbe
from appliance.decision.lost_tracks import LostTrack
from appliance.decision.occlusion import CoastProbe
from appliance.decision.standing import CorridorProbe, StandingState
from appliance.decision.tracking import ImageModel, TrackerState
from appliance.decision.warnings import WarningState
from appliance.messages import ProbabilityMap, TrackReport, WarningEvent
from appliance.vision.geometry import FloatArray

# a probe's key: ("cue", track uid, cue name), ("cover" / "course", hidden track id, "") or
# ("obstacle", 0, "")
ProbeKey = tuple[str, int, str]

@dataclass(frozen=True)
class DecisionState:
    """Everything the decision stage carries from one frame to the next (frozen)."""

    model: ImageModel = field(repr=False)
    prob: NDArray[np.float32]
    tracker: TrackerState
    cues: dict[int, TrackCues]
    warning: WarningState
    body_pitch: float
    pose: CameraPose | None
    t: float | None
    lost: tuple[LostTrack, ...] = ()
    odo: tuple[float, float, float] = (0.0, 0.0, 0.0)  # vehicle x, y (m), heading (rad), odometry frame
    speed: float | None = None   # m/s, the last known CAN speed
    accel: float = 0.0           # m/s^2, its low-passed slope (FrameContext.accel)
    standing: StandingState | None = None   # what stands in the path (standing.py)


SPANNING = (CorridorProbe, HaltProbe)   # the probes measured over several frames


@dataclass(frozen=True)
class Observation:
    """What :func:`observe` found this frame, for :func:`decide`: the frame's context, p(x),
    its clusters, the image tracks, the hidden tracks, and the probes by key (``requests``
    gives vision their pixels)."""

    frame_index: int
    frame: FrameContext
    body_pitch: float
    prob: NDArray[np.float32]
    clusters: tuple[Cluster, ...]
    tracker: TrackerState
    lost: tuple[LostTrack, ...]
    probes: dict[ProbeKey, Probe | CoastProbe | CorridorProbe | HaltProbe]

    def requests(self) -> dict[ProbeKey, FloatArray]:
        """The pixels (M, 2) of the current frame whose flow since the previous frame each
        probe needs."""
        return {k: p.points for k, p in self.probes.items() if not isinstance(p, SPANNING)}

    def spanning_requests(self) -> dict[ProbeKey, tuple[FloatArray, FloatArray, int]]:
        """The probes measured over several frames: their pixels (M, 2) of the current frame,
        where each search starts (M, 2) in the frame ``frames_back`` frames ago, and that
        number."""
        return {k: (p.points, p.guess, p.frames_back) for k, p in self.probes.items()
                if isinstance(p, SPANNING)}


@dataclass(frozen=True)
class DecisionOutput:
    """What one frame of the decision stage produced: p(x), the clusters, every confirmed
    (and every assessed hidden) track's report, the warning changes, the issued level and the
    report behind it."""

    prob_map: ProbabilityMap
    clusters: tuple[Cluster, ...]
    tracks: tuple[TrackReport, ...]
    warnings: tuple[WarningEvent, ...]
    warning_level: int
    warning_track: TrackReport | None
