"""What a confirmed track's cues say of its threat: time to collision, distance, bearing, and
whether its predicted path meets the ego corridor (``threat.py`` has the geometry and how
the ground and scale cues combine). Facts only: whether they suffice to warn is decided in
one place, ``warnings.indication``.

Without the ego motion (vehicle CAN stale or absent, PTU lost: ``FrameContext.ego_known``) a
path over ground means nothing: the 3-D state was predicted with a speed that is not the car's.
The threat is then judged as a monocular system without odometry would judge it, from what
needs no ego speed: the growth of the track's image (its time to contact) and its bearing
(constant: a collision course), and ``warnings`` caps it at a caution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from appliance.config import WarningConfig
from appliance.decision.cues import TrackCues
from appliance.decision.cues.bearing import bearing_rate
from appliance.decision.cues.peaks import clip_box
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import ground_in_camera, road_axis
from appliance.decision.threat import (
    bumper_ttc,
    constant_bearing_course,
    contact_depth_per_px,
    fuse,
    ground_ttc_std,
    near_side_gap,
    object_radius,
    path_expansion,
    predict_path,
    scale_lateral_miss,
    significant_acceleration,
    significant_speed,
    significant_velocity,
)
from appliance.decision.tracking import ImageTrack
from appliance.messages import TrackReport

FAR_CONTACT_M_PER_PX = 1.0   # m of depth per image row beyond which a ground contact cannot
                              # tell a car closing at the ego speed from one driving along
CORRIDOR_HYSTERESIS_M = 0.3   # m, an issued level is kept while the path meets the corridor widened by this
BEARING_TOLERANCE_RAD = 0.02  # rad, without a range: bearing change until contact that still counts
                              # as a constant-bearing collision course
VELOCITY_SIGNIFICANCE = 2.0   # a velocity component (vehicle x, y) smaller than this many std is predicted as 0
ACCELERATION_SIGNIFICANCE = 1.0  # an acceleration counts in full from this many std up, not below this less 1


@dataclass(frozen=True)
class TrackThreat:
    """What the cues say of one confirmed track this frame.

    report: its row of ``tracks.jsonl`` (ttc_s None: no contact predicted, or unknown);
    on_course: its path meets the corridor (``warning.corridor_margin_m``); on_course_wide: the
    corridor widened by ``CORRIDOR_HYSTERESIS_M``; miss_m: by how much its path misses the
    corridor, where known; miss_ahead: that miss is a gap kept ahead in the corridor (the path
    stays in front of the car), not one beside it; moving: it has shown independent motion over
    ground; speed_m_s: the speed over ground it moves at least, at ``VELOCITY_SIGNIFICANCE``
    std (None without a 3-D state); height_m: the tallest its box has been at its depth, None
    where its depth is unknown; coasted: a hidden track assessed from its coasted 3-D state;
    evidence: the probability tested against ``min_probability`` when it is not the track's own
    (:func:`warnings.pool_covered`), else None; standing: an obstacle standing in the path
    (``standing.py``), static by construction, its evidence its parallax; roadside: such an
    obstacle continues the roadside (the outside of a bend the path is predicted straight into);
    closing: how much nearer such an obstacle comes per metre driven (None: not yet known);
    stopped: such an obstacle continues the track of a mover that came to a stop (handover.py);
    suspected: such an obstacle whose evidence has not yet reached the threshold (raises at
    most a caution); growth: (k the path implies, k measured, its std) in 1/s, the expansion
    rate of its image its predicted velocity implies (``threat.path_expansion``) and the one the
    scale cue measures once trusted, where the ground contact is far (one image row spans
    ``FAR_CONTACT_M_PER_PX`` or more of depth: its rows cannot measure the speed along the line
    of sight, which the 3-D state then takes from its prior, standing), else None;
    grows_standing: its image, where the scale cue is trusted, grows nearer as an object standing
    where it is would than as its predicted path implies (a patch of road the tracker drags
    along ahead of the car, its 3-D state moving with the car)."""

    report: TrackReport
    on_course: bool
    on_course_wide: bool
    miss_m: float | None = None
    miss_ahead: bool = False
    moving: bool = True
    speed_m_s: float | None = None
    height_m: float | None = None
    coasted: bool = False
    evidence: float | None = None
    ego_known: bool = True
    standing: bool = False
    roadside: bool = False
    closing: float | None = None
    stopped: bool = False
    suspected: bool = False
    growth: tuple[float, float, float] | None = None
    grows_standing: bool = False

    @property
    def ttc(self) -> float | None:
        return self.report.ttc_s


def assess(track: ImageTrack, cues: TrackCues, f: FrameContext, cfg: WarningConfig,
           coasted: bool = False) -> TrackThreat:
    """TTC, distance, bearing and the corridor test for one confirmed track (threat.py)."""
    mount, camera = f.mount, f.camera
    speed, yaw = f.speed, f.yaw_rate
    bearings = cues.get("bearing")
    brg = bearings.last if bearings is not None else None
    depth_state = cues.get("depth")
    cue_depth = depth_state.depth if depth_state is not None else None
    ground_state = cues.get("ground")
    motion = cues.get("motion")
    moving = motion.moved if motion is not None else False
    scale_state = cues.get("scale")
    scale = scale_state.ttc if scale_state is not None and not coasted else None
    distance: float | None = None
    miss: float | None = None
    miss_ahead = False
    ground_est: tuple[float, float] | None = None
    growth: tuple[float, float, float] | None = None
    grows_standing = False
    on_course = on_wide = False
    depth: float | None = None
    g = cues.ground
    ego_known = f.ego_known
    if g is not None and ego_known:
        pos = g.position
        # a velocity is as significant as it was when last measured: coasting (no contact
        # this frame, or hidden) adds uncertainty, not evidence that the object stopped
        vel = significant_velocity(g.velocity, g.measured_covariance, VELOCITY_SIGNIFICANCE)
        depth = float(pos[0] - mount.x_m)
        rng = float(np.hypot(pos[0] - mount.x_m, pos[1] - mount.y_m))
        radius = object_radius(track.size[0], rng, camera.fx)
        distance = near_side_gap(pos, radius, mount, f.sensors.pan_rad)
        # braking or speeding up, where the state estimates it
        acc = significant_acceleration(vel, g.acceleration, g.P, ACCELERATION_SIGNIFICANCE)
        # and the car's own braking, from its CAN speed: a driver braking already
        # comes to a stop in its stopping distance
        base = predict_path(pos, vel, speed, yaw, mount, cfg.corridor_margin_m, radius,
                            cfg.horizon_s, acc, f.braking)
        wide = predict_path(pos, vel, speed, yaw, mount,
                            cfg.corridor_margin_m + CORRIDOR_HYSTERESIS_M, radius, cfg.horizon_s,
                            acc, f.braking)
        on_course, on_wide = base.ttc is not None, wide.ttc is not None
        miss = None if on_course else base.closest
        miss_ahead = not on_course and base.ahead
        ttc_g = base.ttc if base.ttc is not None else wide.ttc
        axis = road_axis(f.pose)
        if scale_state is not None and scale_state.trusted and not coasted and axis is not None:
            # what its image's growth says of its path: k = c / Z, moving and standing
            z_cam = float(ground_in_camera(f.pose, pos)[2])
            implied = path_expansion(z_cam, axis, vel, speed)
            standing_k = path_expansion(z_cam, axis, np.zeros(2), speed)
            k = scale_state.scale.k
            if implied is not None and standing_k is not None:
                grows_standing = abs(k - standing_k) < abs(k - implied)
                if contact_depth_per_px(rng, camera.fy, f.pose.position[2]) \
                        >= FAR_CONTACT_M_PER_PX:
                    growth = (implied, k, float(np.sqrt(scale_state.scale.var)))
        if ttc_g is not None:
            ground_est = (ttc_g, ground_ttc_std(pos, g.P, ttc_g, speed, vel))
    if g is not None and not ego_known:
        # the contact's geometry needs no ego speed: its distance and depth still hold
        depth = float(g.position[0] - mount.x_m)
        rng = float(np.hypot(g.position[0] - mount.x_m, g.position[1] - mount.y_m))
        distance = near_side_gap(g.position, object_radius(track.size[0], rng, camera.fx), mount,
                                 f.sensors.pan_rad)
        cue_depth = depth
    scale_est = bumper_ttc(scale, depth if depth is not None else cue_depth, mount) \
        if scale is not None else None
    ttc: float | None = None
    if g is not None and ego_known:
        if ground_est is not None:
            # the scale cue only where the ground contact is unreliable (coasting)
            fresh = ground_state is not None and ground_state.fresh and not coasted
            fused = ground_est if fresh else fuse(ground_est, scale_est)
            ttc = fused[0] if fused is not None else None
    elif scale is not None and scale_est is not None and brg is not None:
        rate = bearing_rate(bearings.history)
        if rate is not None and cue_depth is not None:
            lateral = scale_lateral_miss(cue_depth, brg, rate, 1.0 / scale[0], scale_est[0], mount)
            radius = object_radius(track.size[0], cue_depth, camera.fx)
            half = 0.5 * mount.vehicle_width_m + cfg.corridor_margin_m + radius
            on_course = abs(lateral) <= half
            on_wide = abs(lateral) <= half + CORRIDOR_HYSTERESIS_M
            miss = None if on_course else abs(lateral) - half
        elif rate is not None:
            on_course = constant_bearing_course(brg, rate, scale_est[0], mount,
                                                cfg.corridor_margin_m, BEARING_TOLERANCE_RAD)
            on_wide = on_course or constant_bearing_course(
                brg, rate, scale_est[0], mount, cfg.corridor_margin_m + CORRIDOR_HYSTERESIS_M,
                BEARING_TOLERANCE_RAD)
        ttc = scale_est[0] if on_wide else None
    report = TrackReport(
        id=int(track.id) if track.id is not None else -1,
        bbox=clip_box(track.bbox, camera),
        probability=round(float(track.probability), 4),
        flow=(round(track.velocity[0], 3), round(track.velocity[1], 3)),
        ttc_s=None if ttc is None else round(max(ttc, 0.0), 3),
        distance_m=None if distance is None else round(distance, 2),
        bearing_rad=None if brg is None else round(brg, 4),
    )
    peaks = cues.get("peaks")
    height = None
    if depth is not None and depth > 0.0:
        height = peaks.height_peak_m if peaks is not None else 0.0
    least = None if g is None or not ego_known else significant_speed(
        g.velocity, g.measured_covariance, VELOCITY_SIGNIFICANCE)
    return TrackThreat(report=report, on_course=on_course, on_course_wide=on_wide, miss_m=miss,
                       miss_ahead=miss_ahead, moving=moving, speed_m_s=least, height_m=height,
                       coasted=coasted, ego_known=ego_known, growth=growth,
                       grows_standing=grows_standing)
