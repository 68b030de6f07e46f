"""A mover that comes to a stop in the path: the obstacle found standing there continues its track.

The detector sees independent motion. A pedestrian who stops in the lane, or a lead car that
brakes to a standstill, stops showing any: its image track fades and is dropped, and its
lost 3-D state coasts on at the velocity it last had (lost_tracks.py), off the place where it
now stands. The parallax cue (standing.py) then finds it standing there. It is one object:
the new obstacle takes the id of the confirmed mover whose position is where it stands, so
that the driver's HMI, the logs and the warning's hysteresis see one track and one threat from
moving to standing (:func:`continued`). The mover's position is a live track's that moved and
now moves slower than ``STOPPING_M_S``, or, for a lost track, where it would stand had it
stopped when it was lost (``LostTrack.halted``). While the live track and the obstacle both
describe it, one threat is kept under the id (:func:`one_threat`).

A mover that stopped is known to be an object, not a trick of the parallax at the outside of a
bend: its obstacle does not wait to be seen coming nearer before it may warn
(``TrackThreat.stopped``; the roadside test still applies).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from appliance.config import MountConfig
from appliance.decision.assess import TrackThreat
from appliance.decision.cues import TrackCues
from appliance.decision.standing import Obstacle, path_y
from appliance.vision.geometry import FloatArray

GATE_M = 3.0            # m, an obstacle continues a mover this near along the path ...
GATE_RATIO = 0.25       #   ... or this share of its distance, whichever is larger (the obstacle's
                        #   first depth is biased far while its evidence builds up)
LATERAL_GATE_M = 1.0    # m, beyond the obstacle's lateral extent
STOPPING_M_S = 1.0      # m/s, a live track slower than this over ground may be stopping there


def obstacle_position(ob: Obstacle, mount: MountConfig, curvature: float) -> FloatArray:
    """The obstacle's centre (2,) m in the vehicle frame: ``depth_m`` ahead of the camera on
    the path (``curvature`` 1/m), at the middle of its lateral extent."""
    x = mount.x_m + ob.depth_m
    y = float(path_y(np.array([x]), curvature)[0]) + 0.5 * (ob.lateral_m[0] + ob.lateral_m[1])
    return np.array([x, y])


def continued(ob: Obstacle, mount: MountConfig, curvature: float,
              movers: Iterable[tuple[int, FloatArray]]) -> int | None:
    """The id of the mover (id, position (2,) m in the vehicle frame) that ``ob`` continues:
    the nearest one within ``GATE_M`` (or ``GATE_RATIO`` of its distance) along the path and
    ``LATERAL_GATE_M`` beyond the obstacle's lateral extent; None when none is."""
    centre = obstacle_position(ob, mount, curvature)
    half = 0.5 * (ob.lateral_m[1] - ob.lateral_m[0])
    best: tuple[float, int] | None = None
    for ident, p in movers:
        if not np.all(np.isfinite(p)):
            continue
        along = abs(float(p[0]) - float(centre[0]))
        across = abs(float(p[1]) - float(centre[1]))
        reach = max(GATE_M, GATE_RATIO * max(float(p[0]) - mount.x_m, 0.0))
        if along <= reach and across <= half + LATERAL_GATE_M:
            d = math.hypot(along / reach, across / (half + LATERAL_GATE_M))
            if best is None or d < best[0]:
                best = (d, ident)
    return best[1] if best is not None else None


def mover_height(cues: TrackCues) -> float | None:
    """The tallest (m) a mover's box has been at its depth while seen (the peaks cue), for the
    obstacle's reported box; None where it was never measured."""
    peaks = cues.get("peaks")
    h = peaks.height_peak_m if peaks is not None else 0.0
    return float(h) if h > 0.0 else None


def one_threat(threats: list[TrackThreat], obstacle_id: int) -> list[TrackThreat]:
    """One threat per id where a live track and the obstacle continuing it share
    ``obstacle_id``: the track's while it still moves over ground (it measures the object's
    own motion), else the obstacle's."""
    same = [th for th in threats if th.report.id == obstacle_id]
    if len(same) < 2:
        return threats
    track = next((th for th in same if not th.standing), None)
    keep = track if track is not None and track.moving else \
        next(th for th in same if th.standing)
    return [th for th in threats if th.report.id != obstacle_id or th is keep]
