"""The decision stage (section 4 + the 3-D state): particles in, tracks and warnings out.

``decide(state, frame_index, t, particles, ego, sensors, cfg, camera, images)`` is a pure
function of frozen state: time is an argument, nothing is read from a clock and
there is no randomness, so a replay is deterministic. Per frame:

1. spatio-temporal filter of the particle weights -> p(x) (probability_map.py);
2. threshold, dilation, labelling -> clusters with eqs. 19-20 (clustering.py);
3. the paper's five Kalman tracking rules (tracking.py);
4. per track: the ground contact back-projected with the refined pitch and the
   PTU into a 3-D filter with the ego motion removed (ground_state.py), and the
   scale-change cue (scale_ttc.py);
5. path vs ego corridor and TTC per confirmed track (threat.py);
6. warning levels with persistence, hysteresis and hold (warnings.py).

Tracks lost behind an occluder are kept as coasting 3-D states (lost_tracks.py) and, with
``coast_warn_s``, assessed while the flow where they should be shows something nearer hiding
them and until the flow where their head should be shows them off the coasted course
(occlusion.py); the per-track cues are a TrackCues (track_cues.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.decision.clustering import Cluster, find_clusters
from appliance.decision.crossing_velocity import (
    odometry_step,
    to_odometry,
    windowed_crossing_update,
)
from appliance.decision.ground_state import (
    CameraPose,
    GroundTrack,
    back_project,
    bearing,
    bearing_rate_update,
    bearing_update,
    camera_pose,
    foot_halo_shift,
    ground_absorb,
    ground_contact,
    ground_in_camera,
    ground_predict,
    ground_update,
    range_rate_update,
    road_axis,
    update_body_pitch,
    velocity_prior,
)
from appliance.decision.lost_tracks import (
    LostTrack,
    coast_lost,
    coasted_foot,
    coasted_track,
    reacquire,
)
from appliance.decision.object_extent import Outline, extended, outline
from appliance.decision.occlusion import coasted_course, coasted_cover
from appliance.decision.probability_map import empty_map, spatio_temporal_filter
from appliance.decision.scale_ttc import (
    measure_expansion,
    scale_predict,
    scale_ttc,
    scale_update,
)
from appliance.decision.threat import (
    bumper_ttc,
    constant_bearing_course,
    fuse,
    ground_ttc_std,
    near_side_gap,
    object_radius,
    predict_path,
    scale_lateral_miss,
    significant_acceleration,
    significant_velocity,
)
from appliance.decision.track_cues import TrackCues
from appliance.decision.tracking import ImageModel, ImageTrack, TrackerState, track_step
from appliance.decision.warnings import TrackThreat, WarningState, pool_covered, warning_step
from appliance.messages import (
    EgoMotion,
    ParticleSet,
    ProbabilityMap,
    SensorSample,
    TrackReport,
    WarningEvent,
)
from appliance.vision.geometry import PinholeCamera, euler_to_matrix

BEARING_HISTORY = 10  # frames of bearing kept per track for its rate
OUTLINE_MIN_POINTS = 8  # outline flows the scale cue needs to prefer them to the cluster's
DEPTH_MEMORY_S = 3.0  # s, a depth carried on by the scale cue alone is forgotten after this
BEARING_GATE_SIGMAS = 3.0  # a hidden object's head column further than this (std) from its coasted one is not it


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


@dataclass(frozen=True)
class DecisionOutput:
    """What one frame of the decision stage produced (see the task brief for the fields)."""

    prob_map: ProbabilityMap
    clusters: tuple[Cluster, ...]
    tracks: tuple[TrackReport, ...]
    warnings: tuple[WarningEvent, ...]
    warning_level: int
    warning_track: TrackReport | None


def init_decision_state(cfg: Config, camera: PinholeCamera) -> DecisionState:
    return DecisionState(
        prob=empty_map(camera, cfg.probability_map.scale),
        tracker=TrackerState(),
        cues={},
        warning=WarningState(),
        body_pitch=0.0,
        pose=None,
        t=None,
        model=ImageModel.from_config(cfg.tracking),
    )


def _border_sides(c: Cluster, camera: PinholeCamera, margin: int, member_weight: float,
                  halo_px: float) -> tuple[bool, bool, bool]:
    """Whether the left, right and bottom edges of the cluster's box lie within ``margin`` px,
    plus the particle spacing and the halo, of the image border (any: no ground contact;
    the top does not hide it).

    The box spans sampled particles, so its edge is only known to about their spacing
    ``sqrt(box area / particles)``: an object cut by the border often has no particle
    in its last rows; and the box was shrunk by the halo, which the border cut off.
    """
    u0, v0, u1, v1 = c.bbox
    n = max(int(np.count_nonzero(c.weights >= member_weight)), 1)
    m = margin + halo_px + math.sqrt(max((u1 - u0) * (v1 - v0), 0.0) / n)
    return u0 <= m, u1 >= camera.width - m, v1 >= camera.height - m


def _bearing_pixel(track: ImageTrack, c: Cluster | None, sides: tuple[bool, bool, bool]
                   ) -> tuple[tuple[float, float], str]:
    """Where the track's bearing is measured, and which reference that is.

    The box centre; but a box cut by the left or right image border has its centre pinned
    near the border while the object leaves the image, so its bearing seems constant: a
    collision course to the monocular test. Its inner edge, the object's side nearest the
    image centre, moves with the object: the bearing is taken there ("left" / "right").
    """
    left, right, _ = sides     # of c (:func:`_border_sides`)
    if c is not None:
        u0, v0, u1, v1 = c.bbox
        if left != right:
            return ((u1, 0.5 * (v0 + v1)) if left else (u0, 0.5 * (v0 + v1))), \
                ("left" if left else "right")
    return (float(track.position[0]), float(track.position[1])), "centre"


def _update_cues(cues: TrackCues | None, track: ImageTrack, t: float, dt: float,
                 ego: EgoMotion, sensors: SensorSample, pose: CameraPose, cfg: Config,
                 camera: PinholeCamera, lost: tuple[LostTrack, ...] = (),
                 odo: tuple[float, float, float] = (0.0, 0.0, 0.0), shape: Outline | None = None
                 ) -> tuple[TrackCues, LostTrack | None]:
    """The track's cues after this frame, and the lost track it continues (if its first
    ground contact reacquired one). ``shape``: the track's outline this frame, whose flows
    the scale cue fits (``ground.scale_from_outline``) when there are enough."""
    g = cues.ground if cues else None
    found: LostTrack | None = None
    moved_hold = cues.moved_hold if cues else 0
    s = cues.scale if cues else None
    if g is not None:
        # no contact in the frame before: coasting, at constant velocity
        g = ground_predict(g, dt, sensors, cfg.ground, steady=t - g.t_update > 1.5 * dt)
    if s is not None:
        s = scale_predict(s, dt, cfg.ground.scale_process_std)
    fresh = False
    c = track.cluster
    sides = (False, False, False) if c is None else _border_sides(
        c, camera, cfg.ground.border_margin_px, cfg.clustering.member_weight, 0.5 * cfg.flow.window_px)
    pixel, ref = _bearing_pixel(track, c, sides)
    # a bearing from another reference point (the box reached or left the border) starts anew
    hist = cues.bearings if cues and cues.bearing_ref == ref else ()
    hist = (hist + ((t, bearing(camera, pixel, pose)),))[-BEARING_HISTORY:]
    window = cfg.ground.bearing_window_s
    chist = cues.sightings if cues else ()
    if c is not None and window > 0.0:
        u0, v0, u1, v1 = c.bbox
        ray = odo[2] + bearing(camera, (0.5 * (u0 + u1), 0.5 * (v0 + v1)), pose)
        cam = to_odometry(odo, np.array([pose.position[0], pose.position[1]]))
        chist = chist + ((t, ray, float(cam[0]), float(cam[1]), u1 - u0),)
    chist = tuple(h for h in chist if t - h[0] <= window)
    if c is not None and track.confirmed:
        left, right, bottom = sides
        if not any(sides):
            u0, _, u1, _ = c.bbox
            contact = ground_contact(camera, (0.5 * (u0 + u1), c.foot_v - 0.5), pose, cfg.ground)
            if contact is not None and cfg.ground.foot_halo_correction:
                range_m = math.hypot(contact.z[0] - pose.position[0],
                                     contact.z[1] - pose.position[1])
                shift = foot_halo_shift(range_m, _finite(sensors.speed_m_s) * dt, camera.fy,
                                        pose.position[2], 0.5 * cfg.flow.window_px,
                                        cfg.detection.sigma_p_px)
                foot = min(c.foot_v + shift, float(camera.height))
                contact = ground_contact(camera, (0.5 * (u0 + u1), foot - 0.5), pose, cfg.ground)
            if contact is not None:
                rate = _bearing_rate(hist)
                prior = None if rate is None else velocity_prior(
                    contact.z, rate, _finite(sensors.speed_m_s), _finite(sensors.yaw_rate_rad_s),
                    (cfg.mount.x_m, cfg.mount.y_m), cfg.ground)
                if g is None and lost:
                    found = reacquire(lost, contact, cfg)
                if found is not None and found.cues.ground is not None:
                    # the occluded object is back: its coasted state takes the contact
                    g = ground_update(found.cues.ground, contact, t)
                    if found.cues.bearing_ref == ref:
                        hist = (found.cues.bearings + hist)[-BEARING_HISTORY:]
                    chist = tuple(h for h in found.cues.sightings + chist if t - h[0] <= window)
                    moved_hold = g.updates + cfg.warning.moving_min_frames \
                        if found.cues.moved else 0
                else:
                    g = ground_absorb(g, contact, t, cfg.ground, prior)
                fresh = g.t_update == t
                if fresh and window > 0.0 and g.updates > 1:
                    g = windowed_crossing_update(g, chist, odo, cfg)
                elif fresh and rate is not None and cfg.ground.bearing_rate_std_rad_s > 0.0 \
                        and g.updates > 1:
                    g = bearing_rate_update(g, rate, _finite(sensors.speed_m_s),
                                            _finite(sensors.yaw_rate_rad_s),
                                            (cfg.mount.x_m, cfg.mount.y_m),
                                            cfg.ground.bearing_rate_std_rad_s)
        # a border cuts the box along one axis: what enters or leaves the image there is no
        # expansion, so the scale change is fitted along the other axis only
        axes = tuple(a for a, cut in ((0, left or right), (1, bottom)) if not cut)
        # the scale change of the outline's flows (the whole object), else of the cluster's
        # particles: a pedestrian's are a strip at its feet; a lead car's a strip along its bumper,
        # whose fit rests on the two side edges, which step together and make it bimodal while
        # claiming a smaller variance than the outline's (docs/measurements.md: braking lead car)
        m = None
        if cfg.ground.scale_from_outline and shape is not None \
                and len(shape.positions) >= OUTLINE_MIN_POINTS:
            m = measure_expansion(shape.positions, shape.flows, np.ones(len(shape.positions)),
                                  ego.rotation, camera, axes, cfg.flow.window_px)
        if m is None:
            moving = c.weights >= cfg.clustering.member_weight
            m = measure_expansion(c.positions[moving], c.flows[moving], c.weights[moving],
                                  ego.rotation, camera, axes, cfg.flow.window_px)
        if m is not None:
            s = scale_update(s, m, dt)
            # not before the scale cue itself is trusted (scale_ttc_min_frames): a new track's
            # first expansions (its outline still settling) set a wide initial velocity at once
            if cfg.ground.range_rate_from_scale and fresh and g is not None and dt > 0.0 \
                    and m.kappa > -0.9 and s.n >= cfg.ground.scale_ttc_min_frames:
                var = m.var / ((1.0 + m.kappa) * dt) ** 2 * cfg.ground.range_rate_std_gain ** 2
                g = range_rate_update(g, math.log1p(m.kappa) / dt, var, pose,
                                      _finite(sensors.speed_m_s), cfg.ground.gate_sigmas)
    if g is not None and t - g.t_update > cfg.ground.coast_s:
        g = None
    # depth: from the 3-D state while there is one, then carried on by the expansion rate
    # (dZ/dt = -k Z), so the scale TTC can still be referred to the bumper
    depth, depth_t = (cues.depth, cues.depth_t) if cues else (None, float("-inf"))
    if g is not None:
        depth, depth_t = float(g.x[0] - cfg.mount.x_m), t
    elif depth is not None:
        if s is not None and s.n > 0:
            depth *= math.exp(-s.k * dt)
        if t - depth_t > DEPTH_MEMORY_S:
            depth = None
    if g is not None:
        moved = moves_over_ground(g, cfg) or g.updates < moved_hold
    else:
        moved = cues.moved if cues else False
    if found is not None:
        moved_t = found.cues.moved_t
    else:
        moved_t = cues.moved_t if cues else float("-inf")
    return TrackCues(ground=g, ground_fresh=fresh, scale=s, bearings=hist, bearing_ref=ref,
                     sightings=chist,
                     depth=depth,
                     depth_t=depth_t, moved=moved, moved_hold=moved_hold,
                     moved_t=t if moved else moved_t,
                     peak_probability=max(cues.peak_probability if cues else 0.0,
                                          float(track.probability)),
                     peak_height_m=max(cues.peak_height_m if cues else 0.0,
                                       found.cues.peak_height_m if found else 0.0)), found


def moves_over_ground(g: GroundTrack, cfg: Config) -> bool:
    """The object's velocity over ground is at least ``min_speed_m_s`` and ``moving_sigmas``
    std (Mahalanobis, 2 dof) away from standing still.

    The appliance warns of independently moving objects: a false detection on the
    static scene (road texture in a bend, a parked car) has a velocity over ground
    near zero once its 3-D state has converged, while it can be anywhere before.
    """
    v = g.velocity
    if g.updates < cfg.warning.moving_min_frames or g.speed < cfg.warning.min_speed_m_s:
        return False
    Pv = g.P[2:4, 2:4]
    try:
        m2 = float(v @ np.linalg.solve(Pv, v))
    except np.linalg.LinAlgError:
        return False
    return m2 >= cfg.warning.moving_sigmas ** 2


def closing_step(cues: TrackCues | None, sensors: SensorSample, pose: CameraPose, dt: float,
                 min_speed: float) -> float:
    """How far (m) the camera closes on the track's object along its optical axis in ``dt``:
    the ego vehicle's travel less the object's own along the axis (its 3-D state's velocity over
    ground) for an object moving over ground at ``min_speed`` (m/s, a vehicle) or faster; the
    ego vehicle's travel alone for a slower one or one without a 3-D state (as if static).

    The object's image grows by this over its depth per frame: a pedestrian crossing ahead at
    30 km/h expands by 0.02 per frame at 14 m, a lead car at the ego's speed not at all (with
    the ego's travel alone, its outline expected its roof 40 px above the box to move 1.3 px a
    frame up, and the outline never left its bumper). A pedestrian's velocity along the axis
    is the least certain part of its 3-D state (+2 m/s off at 35 m): for slow objects the
    static assumption is the better one (measured: nearside pedestrians warned up to 0.17 s
    later with their state's velocity).
    """
    speed = _finite(sensors.speed_m_s)
    g = cues.ground if cues else None
    d = road_axis(pose)
    if g is None or d is None or g.speed < min_speed:
        return speed * dt
    return float(speed * d[0] - d @ g.velocity) * dt


def _outline(tr: ImageTrack, cues: TrackCues | None, pose: CameraPose,
             images: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None, step_m: float,
             cfg: Config, camera: PinholeCamera, ego: EgoMotion) -> Outline | None:
    """The track's outline (object_extent.py) when its depth (:func:`outline_depth`) is known
    and the frame pair is there; else None (reported as tracked)."""
    if cfg.tracking.outline_max_height_m <= 0.0 or images is None:
        return None
    depth = outline_depth(tr, cues, pose, camera)
    if depth is None:
        return None
    return outline(images[0], images[1], tr.bbox, depth, camera, cfg.flow,
                   step_m / depth, cfg.tracking.outline_max_height_m,
                   cfg.tracking.outline_tolerance, rotation=euler_to_matrix(ego.rotation))


def outline_depth(tr: ImageTrack, cues: TrackCues | None, pose: CameraPose,
                  camera: PinholeCamera) -> float | None:
    """Camera depth (m) at which a track's outline is measured: its 3-D state's (last
    frame's) or, without one, the road's under the bottom of its cluster. An object further
    than ``ground.max_range_m`` (a cyclist at 70 m) has no 3-D state, but the outline needs
    its depth only roughly (how many pixels 2 m are there), not as a measurement of its
    position. None above the horizon, nearer than 0.5 m, or with neither."""
    g = cues.ground if cues is not None else None
    if g is not None:
        foot = ground_in_camera(pose, g.position)
    elif tr.cluster is not None:
        u0, _, u1, _ = tr.cluster.bbox
        road = back_project(camera, np.array([[0.5 * (u0 + u1), tr.cluster.foot_v - 0.5]]), pose)[0]
        if not np.all(np.isfinite(road)):
            return None
        foot = ground_in_camera(pose, road)
    else:
        return None
    return float(foot[2]) if foot[2] > 0.5 else None


def _clip_box(box: tuple[float, float, float, float], camera: PinholeCamera
              ) -> tuple[float, float, float, float]:
    """The track box inside the image, rounded to 0.1 px (a coasting track may drift out)."""
    u0, v0, u1, v1 = box
    w, h = float(camera.width), float(camera.height)
    return (round(min(max(u0, 0.0), w), 1), round(min(max(v0, 0.0), h), 1),
            round(min(max(u1, 0.0), w), 1), round(min(max(v1, 0.0), h), 1))


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


def _bearing_rate(hist: tuple[tuple[float, float], ...]) -> float | None:
    if len(hist) < 3:
        return None
    ts = np.array([h[0] for h in hist])
    bs = np.unwrap(np.array([h[1] for h in hist]))
    if ts[-1] - ts[0] <= 0.0:
        return None
    return float(np.polyfit(ts - ts[-1], bs, 1)[0])


def assess(track: ImageTrack, cues: TrackCues, sensors: SensorSample, cfg: Config,
           camera: PinholeCamera) -> TrackThreat:
    """TTC, distance, bearing and the corridor test for one confirmed track (threat.py)."""
    mount, w = cfg.mount, cfg.warning
    speed = sensors.speed_m_s if math.isfinite(sensors.speed_m_s) else 0.0
    yaw = sensors.yaw_rate_rad_s if math.isfinite(sensors.yaw_rate_rad_s) else 0.0
    brg = cues.bearings[-1][1] if cues.bearings else None
    distance: float | None = None
    ground_est: tuple[float, float] | None = None
    on_course = on_wide = False
    depth: float | None = None
    g = cues.ground
    if g is not None:
        pos = g.position
        # a velocity is as significant as it was when last measured: coasting (no contact
        # this frame, or hidden) adds uncertainty, not evidence that the object stopped
        vel = significant_velocity(g.velocity, g.measured_covariance,
                                   w.velocity_significance_sigmas, w.velocity_conditioning)
        depth = float(pos[0] - mount.x_m)
        rng = float(np.hypot(pos[0] - mount.x_m, pos[1] - mount.y_m))
        radius = object_radius(track.size[0], rng, camera.fx)
        distance = near_side_gap(pos, radius, mount, sensors.pan_rad)
        # braking or speeding up, where the state estimates it (ground.accel_min_speed_m_s)
        acc = significant_acceleration(vel, g.acceleration, g.P, w.acceleration_significance_sigmas)
        base = predict_path(pos, vel, speed, yaw, mount, w.corridor_margin_m, radius, w.horizon_s,
                            acc)
        wide = predict_path(pos, vel, speed, yaw, mount,
                            w.corridor_margin_m + w.corridor_hysteresis_m, radius, w.horizon_s,
                            acc)
        on_course, on_wide = base.ttc is not None, wide.ttc is not None
        ttc_g = base.ttc if base.ttc is not None else wide.ttc
        if ttc_g is not None:
            ground_est = (ttc_g, ground_ttc_std(pos, g.P, ttc_g, speed, vel))
    scale = scale_ttc(cues.scale, cfg.ground.scale_ttc_min_frames)
    scale_est = bumper_ttc(scale, depth if depth is not None else cues.depth, mount) \
        if scale is not None else None
    ttc: float | None = None
    if g is not None:
        if ground_est is not None:
            # the scale cue only where the ground contact is unreliable (coasting)
            fused = ground_est if cues.ground_fresh else fuse(ground_est, scale_est)
            ttc = fused[0] if fused is not None else None
    elif scale is not None and scale_est is not None and brg is not None:
        rate = _bearing_rate(cues.bearings)
        if rate is not None and cues.depth is not None:
            miss = scale_lateral_miss(cues.depth, brg, rate, 1.0 / scale[0], scale_est[0], mount)
            radius = object_radius(track.size[0], cues.depth, camera.fx)
            half = 0.5 * mount.vehicle_width_m + w.corridor_margin_m + radius
            on_course = abs(miss) <= half
            on_wide = abs(miss) <= half + w.corridor_hysteresis_m
        elif rate is not None:
            on_course = constant_bearing_course(brg, rate, scale_est[0], mount, w.corridor_margin_m,
                                                w.bearing_tolerance_rad)
            on_wide = on_course or constant_bearing_course(
                brg, rate, scale_est[0], mount, w.corridor_margin_m + w.corridor_hysteresis_m,
                w.bearing_tolerance_rad)
        ttc = scale_est[0] if on_wide else None
    report = TrackReport(
        id=int(track.id) if track.id is not None else -1,
        bbox=_clip_box(track.bbox, camera),
        probability=round(float(track.probability), 4),
        flow=(round(track.velocity[0], 3), round(track.velocity[1], 3)),
        ttc_s=None if ttc is None else round(max(ttc, 0.0), 3),
        distance_m=None if distance is None else round(distance, 2),
        bearing_rad=None if brg is None else round(brg, 4),
    )
    # a road user stands up from its ground contact: its box, now or at some time it was seen
    # (a hidden, coasted track keeps the strip it was lost with), is at least min_height_m tall
    height: float | None = None
    upright = True
    if g is not None and depth is not None and depth > 0.0:
        if track.cluster is not None:
            height = (report.bbox[3] - report.bbox[1]) * depth / camera.fy
        upright = max(height or 0.0, cues.peak_height_m) >= w.min_height_m
    fast = g is not None and cues.moved and w.fast_mover_m_s > 0.0 \
        and g.speed >= w.fast_mover_m_s
    return TrackThreat(report=report, on_course=on_course, on_course_wide=on_wide,
                       moving=cues.moved, upright=upright, height_m=height, fast=fast)


def decide(state: DecisionState, frame_index: int, t: float, particles: ParticleSet,
           ego: EgoMotion, sensors: SensorSample, cfg: Config, camera: PinholeCamera,
           images: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None
           ) -> tuple[DecisionState, DecisionOutput]:
    """One frame of the decision stage; see the module docstring. ``images``: the previous and
    this frame (8-bit gray), for the tracks' outlines (object_extent.py) and the occlusion
    test of coasted tracks (occlusion.py); None: neither is measured (tracks are reported
    with their cluster boxes, a coasted track counts as not hidden when the test is on)."""
    fps = cfg.camera.fps
    dt = (t - state.t) if state.t is not None and t > state.t else 1.0 / fps
    model = state.model
    body_pitch = state.body_pitch
    if state.pose is not None:
        body_pitch = update_body_pitch(body_pitch, ego, state.pose, dt, cfg.ground)
    pose = camera_pose(cfg.mount, body_pitch, sensors)
    odo = odometry_step(state.odo, _finite(sensors.speed_m_s), _finite(sensors.yaw_rate_rad_s), dt) \
        if state.t is not None else state.odo

    prob = spatio_temporal_filter(state.prob, particles, ego.rotation, camera, cfg.probability_map)
    clusters = find_clusters(prob, cfg.probability_map.scale, particles, cfg.clustering,
                             (camera.width, camera.height), halo_px=0.5 * cfg.flow.window_px)
    tracker = track_step(state.tracker, clusters, cfg.tracking, model)

    lost = coast_lost(state.tracker, state.cues, state.lost, tracker, t, dt, sensors, cfg)
    cues: dict[int, TrackCues] = {}
    threats: list[TrackThreat] = []
    tracks = list(tracker.tracks)
    for i, tr in enumerate(tracks):
        before = state.cues.get(tr.uid)
        shape = _outline(tr, before, pose, images,
                         closing_step(before, sensors, pose, dt, cfg.ground.accel_min_speed_m_s),
                         cfg, camera, ego) if tr.confirmed else None
        cues[tr.uid], found = _update_cues(before, tr, t, dt, ego, sensors, pose,
                                           cfg, camera, lost, odo, shape)
        if found is not None:
            # the reacquired track continues the lost one under its id
            lost = tuple(lt for lt in lost if lt is not found)
            tracks[i] = tr = replace(tr, id=found.id)
        if tr.confirmed:
            if shape is None:   # a 3-D state started this frame: outline it with that
                shape = _outline(tr, cues[tr.uid], pose, images,
                                 closing_step(cues[tr.uid], sensors, pose, dt,
                                              cfg.ground.accel_min_speed_m_s), cfg, camera, ego)
            shown = tr if shape is None else extended(tr, shape.top)
            th = assess(shown, cues[tr.uid], sensors, cfg, camera)
            if th.height_m is not None and th.height_m > cues[tr.uid].peak_height_m:
                cues[tr.uid] = replace(cues[tr.uid], peak_height_m=th.height_m)
            threats.append(th)
    tracker = replace(tracker, tracks=tuple(tracks))
    if cfg.warning.pool_covered_tracks:
        threats = pool_covered(threats)
    if cfg.tracking.coast_warn_s > 0.0:
        seen: list[LostTrack] = []
        for lt in lost:
            coasted = coasted_track(lt, t, pose, cfg, camera)
            foot = coasted_foot(lt, pose)
            if coasted is not None and cfg.tracking.coast_cover_ratio > 0.0:
                ratio = coasted_cover(coasted[0], foot, images, ego, sensors, dt, cfg.flow, camera)
                lt = replace(lt, cover=(*lt.cover[1 - cfg.tracking.coast_cover_frames:], ratio))
            if coasted is not None and cfg.tracking.coast_course_points > 0.0 and not lt.off_course:
                count, column = coasted_course(coasted[0], foot, lt.cues.peak_height_m, images, ego,
                                               sensors, dt, cfg.flow, camera,
                                               cfg.tracking.coast_course_ratio)
                lt = lt.with_course(count, cfg)
                g, std_px = lt.cues.ground, cfg.tracking.coast_bearing_std_px
                if g is not None and lt.seen_on_course and not lt.off_course and std_px > 0.0 \
                        and count >= cfg.tracking.coast_course_points \
                        and abs(column - float(coasted[0].x[0, 0])) <= BEARING_GATE_SIGMAS * std_px:
                    # the head keeping its bearing is where the hidden object is, across the ray
                    azimuth = bearing(camera, (column, float(coasted[0].x[1, 0])), pose)
                    g = bearing_update(g, azimuth, (pose.position[0], pose.position[1]),
                                       std_px / camera.fx)
                    lt = replace(lt, cues=replace(lt.cues, ground=g))
                    coasted = coasted_track(lt, t, pose, cfg, camera)
            seen.append(lt)
            if coasted is not None and lt.covered(cfg) and not lt.off_course:
                threats.append(replace(assess(*coasted, sensors, cfg, camera), coasted=True))
        lost = tuple(seen)
    threats.sort(key=lambda th: th.report.id)
    warning, events, warned = warning_step(state.warning, tuple(threats), t, frame_index,
                                           cfg.warning, frame_dt=dt,
                                           released=frozenset(lt.id for lt in lost
                                                              if lt.off_course))
    new_state = DecisionState(prob=prob, tracker=tracker, cues=cues, warning=warning,
                              body_pitch=body_pitch, pose=pose, t=t, model=model, lost=lost,
                              odo=odo)
    out = DecisionOutput(
        prob_map=ProbabilityMap(p=prob, scale=cfg.probability_map.scale),
        clusters=clusters,
        tracks=tuple(th.report for th in threats),
        warnings=events,
        warning_level=warning.level,
        warning_track=warned,
    )
    return new_state, out
