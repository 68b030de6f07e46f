"""Does a lost mover stand where it stopped? The flow where it would stand says so.

A pedestrian who stops in the lane stops showing independent motion: its image track fades
and is dropped (lost_tracks.py), and its lost 3-D state coasts on, off the place where it now
stands. The parallax cue (standing.py) finds what stands in the path without knowing where to
look, and needs many points measured to reach its evidence: a pedestrian in plain clothes
shows flow only at its outline and its head, and is found late or not at all. The lost track
knows where to look: where it would stand had it stopped when it was lost
(``LostTrack.halted``), at the height its track showed, if it was lost slow enough to stop
there (``HALT_SPEED_M_S``).

:func:`halt_probe` names a grid of pixels over the box such an object would fill there, from
the row where the road seen above its feet lies 1 / ``ROAD_RATIO`` times farther than the object
up to its height (lower, the road just behind its feet is at nearly its depth), and vision
measures their flow over the last ``standing.BASELINE_S`` (a static surface 20 m ahead moves
a fraction of a pixel per frame). :func:`halt_count` counts the points whose translational
flow is that of a static surface at the object's depth (:func:`occlusion.flow_ratios`: a ratio
within ``STANDS_RATIO``; the road seen there is farther, its ratio ``ROAD_RATIO`` or less; the
background above the horizon farther still). Where the median of the last ``HALT_FRAMES``
counts reaches ``HALT_POINTS``, something stands where the mover stopped
(:meth:`LostTrack.stands`): it is assessed as an obstacle standing there (:func:`halted_threat`),
under the mover's id, and kept while it is seen standing. A mover that walked on leaves the road
and the background in that box; what else stands there at that depth (a parked car beside a
pedestrian who walked on along the kerb) stands there too, and is judged by its place like any
obstacle: in the path or not. Where the mover is assessed otherwise (hidden, what stands there
may be the occluder; the parallax cue's obstacle at its place), that is its threat
(``decide.decide``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from appliance.config import WarningConfig
from appliance.decision.assess import TrackThreat
from appliance.decision.frame import FrameContext, Motion, frame_motion
from appliance.decision.ground_state import CameraPose, ground_in_camera
from appliance.decision.handover import mover_height
from appliance.decision.lost_tracks import HALT_FRAMES, LostTrack
from appliance.decision.occlusion import band_points, flow_ratios
from appliance.decision.standing import BASELINE_S, Obstacle, compose, obstacle_threat, path_y
from appliance.vision.geometry import FloatArray, PinholeCamera
from appliance.vision.probes import PointFlow

ROAD_RATIO = 0.55             # the probed box's bottom: the row where the road seen lies 1 / this
                              #   times farther than the object (0.54 m above the road for a camera
                              #   1.2 m high, 0.74 m for one 1.65 m high), and 0.5 m at least
HALT_SPEED_M_S = 4.0          # m/s over ground, the fastest a mover is lost at and may stand where it
                              #   was (a walker stops within a step; a car or a cyclist at speed
                              #   runs on for metres, and what stands there is something else)
HALT_HEIGHT_M = 1.5           # m, the height probed where the mover's own was never measured
MIN_WIDTH_M = 0.6             # m, the probed box is at least this wide (a lost box is often a remnant)
GRID_PX = 2.0                 # px between the probed points (an outline is seen by the few whose
GRID_MAX = (24, 40)           #   window holds it); points across and down at most
STANDS_RATIO = (0.7, 1.6)     # a point at the object's depth: its flow ratio (the depth is known to
                              #   about 20 %)


def halted_width_m(lt: LostTrack, camera: PinholeCamera) -> float:
    """How wide (m) the lost mover's track was at its depth, ``MIN_WIDTH_M`` at least."""
    depth_state = lt.cues.get("depth")
    then = depth_state.depth if depth_state is not None else None
    if lt.track is None or then is None or then <= 0.5:
        return MIN_WIDTH_M
    return max(MIN_WIDTH_M, lt.track.size[0] * then / camera.fx)


def halted_box(lt: LostTrack, pose: CameraPose, camera: PinholeCamera
               ) -> tuple[tuple[float, float, float, float], float] | None:
    """Where a lost mover that stopped would be in the image: the box (u0, v0, u1, v1) px of
    its probed part (from where the road seen above its feet lies 1 / ``ROAD_RATIO`` times
    farther up to its height, :func:`halted_width_m` wide) and its camera depth (m); None
    without a halted position, or less than 0.5 m ahead."""
    if lt.halted is None:
        return None
    foot = ground_in_camera(pose, lt.halted)
    depth = float(foot[2])
    if depth <= 0.5:
        return None
    height = mover_height(lt.cues) or HALT_HEIGHT_M
    u, v = (float(c) for c in camera.project(foot[None])[0])
    px = camera.fy / depth
    half = 0.5 * halted_width_m(lt, camera) * camera.fx / depth
    bottom = max(0.5, (1.0 - ROAD_RATIO) * float(pose.position[2]))
    return (u - half, v - height * px, u + half, v - bottom * px), depth


@dataclass(frozen=True)
class HaltProbe:
    """Pixels (M, 2) of the current frame over where a lost mover would stand, measured over
    ``frames_back`` frames (a static surface's flow at 20 m is a fraction of a pixel per
    frame), each search starting at ``guess`` (M, 2), where a static point at the object's
    camera depth ``depth_m`` was then; the camera's motion over those frames (R (3, 3), t_m (3,)
    m, ``X_cur = R X_then + t``)."""

    points: FloatArray
    guess: FloatArray
    frames_back: int
    depth_m: float
    R: FloatArray
    t_m: FloatArray


def halt_probe(lt: LostTrack, f: FrameContext, motions: tuple[Motion | None, ...]
               ) -> HaltProbe | None:
    """The points of :func:`halt_count` for a lost track with a halted position, measured over
    the last ``standing.BASELINE_S`` (``motions``: the frame motions before this one, oldest
    first); None when it was lost faster than ``HALT_SPEED_M_S`` or cannot be measured
    (standstill, speed unknown, out of the image)."""
    g = lt.cues.ground
    if g is not None and g.speed > HALT_SPEED_M_S:
        return None
    placed = halted_box(lt, f.pose, f.camera)
    now = frame_motion(f.ego, f.sensors, f.dt)
    if placed is None or now is None:
        return None
    box, depth = placed
    if not (box[2] > box[0] and box[3] > box[1]):   # a mover no taller than the probed bottom
        return None
    pts = band_points(box, f.camera.width, f.camera.height, GRID_PX, GRID_MAX)
    if len(pts) == 0:
        return None
    frames = max(1, int(round(BASELINE_S / f.dt))) if f.dt > 0.0 else 1
    (R, t_m), back = compose(motions, now, frames)
    # where a static point at the object's depth seen there was ``back`` frames ago
    x_cur = np.column_stack([f.camera.undistort(pts), np.ones(len(pts))]) @ f.camera.K_inv.T
    guess = f.camera.project((x_cur * depth - t_m) @ R)   # R^T (X - t)
    guess = np.where(np.isfinite(guess), guess, pts)
    return HaltProbe(pts, guess, back, depth, R, t_m)


def halt_count(p: HaltProbe, flow: PointFlow | None, camera: PinholeCamera) -> float:
    """How many of the probe's points flow as a static surface at its depth does (a ratio
    within ``STANDS_RATIO``, :func:`occlusion.flow_ratios`)."""
    ratio = flow_ratios(p.points, flow, p.depth_m, p.R, p.t_m, camera)
    ok = np.isfinite(ratio)
    return float(np.count_nonzero(ok & (ratio >= STANDS_RATIO[0]) & (ratio <= STANDS_RATIO[1])))


def halted_threat(lt: LostTrack, f: FrameContext, cfg: WarningConfig,
                  evidence_threshold: float) -> TrackThreat | None:
    """The threat of a lost mover seen standing where it stopped: an obstacle under its id at
    its halted position, as wide as its track was (at least ``MIN_WIDTH_M``), as tall as it
    was seen; its evidence the threshold's (it is known to be an object). None for a track
    that never showed the probability of independent motion a level needs
    (``warning.min_probability``, its highest while seen): a patch of static scenery the
    tracker followed for a while, not a mover."""
    peaks = lt.cues.get("peaks")
    if lt.halted is None or peaks is None or peaks.probability < cfg.min_probability \
            or halted_box(lt, f.pose, f.camera) is None:
        return None
    half = 0.5 * halted_width_m(lt, f.camera)
    x, y = float(lt.halted[0]), float(lt.halted[1])
    curvature = f.yaw_rate / f.speed if f.speed > 0.1 else 0.0
    centre = y - float(path_y(np.array([x]), curvature)[0])
    ob = Obstacle(id=lt.id, depth_m=x - f.mount.x_m, lateral_m=(centre - half, centre + half),
                  evidence=evidence_threshold, since=f.t, seen=f.t, stopped=True,
                  top_m=mover_height(lt.cues) or HALT_HEIGHT_M)
    return obstacle_threat(ob, f, cfg, evidence_threshold)


def halted_probes(lost: tuple[LostTrack, ...], f: FrameContext,
                  motions: tuple[Motion | None, ...]) -> dict[tuple[str, int, str], HaltProbe]:
    """The halt probe ``("halt", id)`` of each lost track with a halted position (``motions``:
    the frame motions before this one, oldest first)."""
    out: dict[tuple[str, int, str], HaltProbe] = {}
    for lt in lost:
        p = halt_probe(lt, f, motions)
        if p is not None:
            out[("halt", lt.id, "")] = p
    return out


def halted_threats(lost: tuple[LostTrack, ...], probes: Mapping[tuple[str, int, str], object],
                   flows: Mapping[tuple[str, int, str], PointFlow], f: FrameContext,
                   cfg: WarningConfig, evidence_threshold: float,
                   assessed: set[int] | frozenset[int] = frozenset()
                   ) -> tuple[tuple[LostTrack, ...], list[TrackThreat]]:
    """The lost tracks after this frame's halt counts, and the threats of those seen standing
    where they stopped, but for those whose ids are ``assessed`` otherwise this frame (the
    parallax cue's obstacle continuing one, a hidden one assessed from its coasted state)."""
    out: list[LostTrack] = []
    threats: list[TrackThreat] = []
    for lt in lost:
        p = probes.get(("halt", lt.id, ""))
        count = halt_count(p, flows.get(("halt", lt.id, "")), f.camera) \
            if isinstance(p, HaltProbe) else float("nan")
        lt = replace(lt, halt=(*lt.halt[1 - HALT_FRAMES:], count))
        if lt.stands():
            lt = replace(lt, standing_seen=f.t)
            th = halted_threat(lt, f, cfg, evidence_threshold) if lt.id not in assessed else None
            if th is not None:
                threats.append(th)
        out.append(lt)
    return tuple(out), threats
