"""Per-track state of the decision stage beyond the image Kalman filters (frozen)."""

from __future__ import annotations

from dataclasses import dataclass

from appliance.decision.crossing_velocity import Sighting
from appliance.decision.ground_state import GroundTrack
from appliance.decision.scale_ttc import ScaleState


@dataclass(frozen=True)
class TrackCues:
    """Per-track state beyond the image filters: 3-D state, scale cue, bearing history."""

    ground: GroundTrack | None = None
    ground_fresh: bool = False
    scale: ScaleState | None = None
    bearings: tuple[tuple[float, float], ...] = ()
    # where the bearings were measured: "centre" of the box, or its inner edge when the
    # box is cut by the "left" / "right" image border (the history restarts when this changes)
    bearing_ref: str = "centre"
    # sightings of the cluster centre (frames with a cluster, the last bearing_window_s): t s, ray
    # direction rad and camera position x, y m in the odometry frame, cluster width px
    sightings: tuple[Sighting, ...] = ()
    depth: float | None = None  # m, camera to object along the vehicle x axis
    depth_t: float = float("-inf")  # s, when the depth last came from the ground state
    moved: bool = False  # moving over ground (from the 3-D state; kept while it is missing)
    moved_hold: int = 0  # a reacquired track counts as moving while its state has fewer contacts
    moved_t: float = float("-inf")  # s, when it last counted as moving
    peak_probability: float = 0.0  # the track's highest (smoothed) eq. 20 probability so far
    peak_height_m: float = 0.0  # the tallest its reported box has been at its depth while seen, m
