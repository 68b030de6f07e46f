"""Hidden tracks: warned of while something nearer covers them, until their head is seen to stop.

A confirmed track lost behind an occluder (a parked car) coasts as a 3-D state
(lost_tracks.py). For ``hidden.warn_s`` after its last ground contact it is assessed like a
seen track from that state, while the flow where it should be shows something nearer
covering it (occlusion.cover_ratio) and until the flow where its head should show above the
occluder says it is no longer on its coasted course (occlusion.course_count). While the head
is seen keeping its bearing, that bearing corrects the coasted position across the line of
sight. The flow at those pixels is measured by vision: :func:`hidden_probes` names them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace

from appliance.config import HiddenConfig, WarningConfig
from appliance.decision.assess import TrackThreat, assess
from appliance.decision.cues import TrackCues
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import bearing, bearing_innovation, bearing_update
from appliance.decision.lost_tracks import (
    COURSE_POINTS,
    COVER_FRAMES,
    LostTrack,
    coasted_foot,
    coasted_track,
)
from appliance.decision.occlusion import (
    CoastProbe,
    course_count,
    course_probe,
    cover_probe,
    cover_ratio,
)
from appliance.vision.probes import PointFlow

BEARING_STD_PX = 2.0       # px, std of a hidden object's head column as a bearing measurement
BEARING_GATE_SIGMAS = 3.0  # a head column further than this from the coasted one is not it (std
#                            of the innovation: the coasted state's across-ray uncertainty and the
#                            head's)


def hidden_probes(lost: tuple[LostTrack, ...], f: FrameContext, cfg: HiddenConfig
                  ) -> dict[tuple[str, int, str], CoastProbe]:
    """The pixels to measure for each hidden track that can still warn: its cover probe
    ``("cover", id)`` and, while it is not known to be off course, its head band ``("course", id)``."""
    out: dict[tuple[str, int, str], CoastProbe] = {}
    if cfg.warn_s <= 0.0:
        return out
    for lt in lost:
        coasted = coasted_track(lt, f.t, f.pose, f.mount.x_m, f.camera, cfg.warn_s)
        if coasted is None:
            continue
        foot = coasted_foot(lt, f.pose)
        p = cover_probe(coasted, foot, f.ego, f.sensors, f.dt, f.camera)
        if p is not None:
            out[("cover", lt.id, "")] = p
        peaks = lt.cues.get("peaks")
        height = peaks.height_peak_m if peaks is not None else 0.0
        c = course_probe(coasted, foot, height, f.ego, f.sensors, f.dt, f.camera)
        if c is not None and not lt.off_course:
            out[("course", lt.id, "")] = c
    return out


def hidden_threats(lost: tuple[LostTrack, ...], probes: Mapping[tuple[str, int, str], object],
                   flows: Mapping[tuple[str, int, str], PointFlow], f: FrameContext, cfg: HiddenConfig,
                   warning: WarningConfig) -> tuple[tuple[LostTrack, ...], list[TrackThreat]]:
    """The hidden tracks after this frame's cover and head tests, and the threats of those
    still covered and not known to be off course."""
    if cfg.warn_s <= 0.0:
        return lost, []
    seen: list[LostTrack] = []
    threats: list[TrackThreat] = []
    nan = float("nan")
    for lt in lost:
        coasted = coasted_track(lt, f.t, f.pose, f.mount.x_m, f.camera, cfg.warn_s)
        if coasted is not None:
            p = probes.get(("cover", lt.id, ""))
            ratio = cover_ratio(p, flows.get(("cover", lt.id, "")), f.camera)[0] \
                if isinstance(p, CoastProbe) else nan
            lt = replace(lt, cover=(*lt.cover[1 - COVER_FRAMES:], ratio))
        if coasted is not None and not lt.off_course:
            c = probes.get(("course", lt.id, ""))
            count, column = course_count(c, flows.get(("course", lt.id, "")), f.camera) \
                if isinstance(c, CoastProbe) else (nan, nan)
            lt = lt.with_course(count)
            g = lt.cues.ground
            if g is not None and lt.seen_on_course and not lt.off_course \
                    and count >= COURSE_POINTS and math.isfinite(column):
                # the head keeping its bearing is where the hidden object is, across the ray,
                # where the coasted state may be (its own uncertainty and the head's: a state
                # coasting on a lateral speed its last sightings underestimated lags behind)
                azimuth = bearing(f.camera, (column, float(coasted.x[1, 0])), f.pose)
                camera_xy = (f.pose.position[0], f.pose.position[1])
                std_rad = BEARING_STD_PX / f.camera.fx
                nu, S = bearing_innovation(g, azimuth, camera_xy, std_rad)
                if nu * nu <= BEARING_GATE_SIGMAS ** 2 * S:
                    g = bearing_update(g, azimuth, camera_xy, std_rad)
                    lt = replace(lt, cues=TrackCues(ground=g, states=lt.cues.states))
                    coasted = coasted_track(lt, f.t, f.pose, f.mount.x_m, f.camera, cfg.warn_s)
        seen.append(lt)
        if coasted is not None and lt.covered() and not lt.off_course:
            threats.append(assess(coasted, lt.cues, f, warning, coasted=True))
    return tuple(seen), threats
