"""What one frame measured of one track, before any cue interprets it.

:class:`FrameContext` holds what every per-track computation of a frame shares (time, the
camera's pose on the road, the CAN sample, the refined ego motion, the odometry pose, and how
vision measured its flows). :func:`measure_track` takes the geometry of one image track in
that frame: which image borders cut its box, the pixel and reference its bearing is taken at,
its ground contact (the bottom of its cluster back-projected onto the road) and its sighting
for the crossing-velocity fit. Pure functions of frozen data; no images.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from appliance.config import MountConfig
from appliance.decision.clustering import MEMBER_WEIGHT, Cluster
from appliance.decision.crossing_velocity import Sighting, to_odometry
from appliance.decision.ground_state import (
    CameraPose,
    GroundContact,
    GroundModel,
    bearing,
    foot_halo_shift,
    ground_contact,
)
from appliance.decision.tracking import ImageTrack
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix

Motion = tuple[FloatArray, FloatArray]   # (R (3, 3), t_m (3,) m): X_cur = R X_prev + t

BORDER_MARGIN_PX = 3   # px, a box this close (plus particle spacing and halo) to a border has no contact
BRAKING_M_S2 = -1.0    # m/s^2, the car brakes when its CAN speed falls faster than this
ACCEL_TAU_S = 0.3      # s, low pass of the CAN speed's slope


def frame_motion(ego: EgoMotion, sensors: SensorSample, dt: float) -> Motion | None:
    """The camera's motion since the previous frame: the refined rotation, the translation
    direction scaled by the CAN speed; None where the speed is unknown or at a standstill."""
    speed = sensors.speed_m_s
    if ego.standstill or not sensors.can_valid or not math.isfinite(speed) or speed <= 0.1:
        return None
    return euler_to_matrix(ego.rotation), \
        np.asarray(ego.translation_dir, dtype=np.float64) * speed * dt


def can_speed(sensors: SensorSample) -> float | None:
    """The CAN speed (m/s) when it is known: finite and fresh; else None."""
    v = sensors.speed_m_s
    return v if sensors.can_valid and math.isfinite(v) else None


def speed_slope(accel: float, prev_speed: float | None, speed: float | None, dt: float) -> float:
    """The CAN speed's slope (m/s^2) low-passed over ``ACCEL_TAU_S``; 0 while the speed is
    unknown (None: no braking that the appliance does not see), kept when it was not known the
    frame before."""
    if speed is None:
        return 0.0
    if prev_speed is None or dt <= 0.0:
        return accel
    w = 1.0 - math.exp(-dt / ACCEL_TAU_S)
    return (1.0 - w) * accel + w * (speed - prev_speed) / dt


@dataclass(frozen=True)
class FrameContext:
    """What the per-track computations of one frame share.

    t, dt: the frame's time and the interval since the previous one (s); pose: the camera on
    the road (refined body pitch, PTU); sensors: CAN and PTU at the frame's capture time, with
    ``speed``, ``yaw_rate`` their finite values (0 where unknown); ego: the refined camera
    motion since the previous frame; odo: the vehicle's pose in the odometry frame (x m, y m,
    heading rad); window_px, flow_std_px: the Lucas-Kanade window vision measured the
    particles' flows with, and their std (sigma_p); accel: the CAN speed's low-passed slope
    (m/s^2, :func:`speed_slope`)."""

    t: float
    dt: float
    pose: CameraPose
    sensors: SensorSample
    ego: EgoMotion
    odo: tuple[float, float, float]
    camera: PinholeCamera
    mount: MountConfig
    window_px: int
    flow_std_px: float
    accel: float = 0.0

    @property
    def braking(self) -> float:
        """The car's own deceleration (m/s^2, negative) while it brakes harder than
        ``BRAKING_M_S2``, else 0: the slope of the CAN speed, low-passed over ``ACCEL_TAU_S``."""
        return self.accel if self.accel < BRAKING_M_S2 else 0.0

    @property
    def speed(self) -> float:
        return finite(self.sensors.speed_m_s)

    @property
    def yaw_rate(self) -> float:
        return finite(self.sensors.yaw_rate_rad_s)

    @property
    def ego_known(self) -> bool:
        """Whether the ego motion is known: vehicle CAN (speed, yaw rate) and the PTU fresh.
        Without it, a path over ground means nothing: see ``assess`` and ``warnings``."""
        return bool(self.sensors.can_valid and self.sensors.ptu_valid
                    and math.isfinite(self.sensors.speed_m_s))

    @property
    def halo_px(self) -> float:
        """Half the LK window: how far beside an object its particles still follow it."""
        return 0.5 * self.window_px


@dataclass(frozen=True)
class TrackMeasurement:
    """The geometry of one image track in one frame.

    sides: whether its cluster's box is cut by the left, right and bottom image border;
    bearing_ref: where its bearing is taken ("centre" of the box, or its inner edge when the
    box is cut by the "left" / "right" border); bearing: that azimuth (rad, vehicle frame);
    contact: its ground contact (confirmed tracks whose box no border cuts, below the
    horizon, within range), else None; sighting: ``(t, ray, camera x, camera y, width px)``
    of its cluster in the odometry frame, None without a cluster."""

    sides: tuple[bool, bool, bool]
    bearing_ref: str
    bearing: float
    contact: GroundContact | None
    sighting: Sighting | None


def finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


def border_sides(c: Cluster, camera: PinholeCamera, margin: int, halo_px: float
                 ) -> tuple[bool, bool, bool]:
    """Whether the left, right and bottom edges of the cluster's box lie within ``margin`` px,
    plus the particle spacing and the halo, of the image border (any: no ground contact;
    the top does not hide it).

    The box spans sampled particles, so its edge is only known to about their spacing
    ``sqrt(box area / particles)``: an object cut by the border often has no particle
    in its last rows; and the box was shrunk by the halo, which the border cut off.
    """
    u0, v0, u1, v1 = c.bbox
    n = max(int(np.count_nonzero(c.weights >= MEMBER_WEIGHT)), 1)
    m = margin + halo_px + math.sqrt(max((u1 - u0) * (v1 - v0), 0.0) / n)
    return u0 <= m, u1 >= camera.width - m, v1 >= camera.height - m


def bearing_pixel(track: ImageTrack, c: Cluster | None, sides: tuple[bool, bool, bool]
                  ) -> tuple[tuple[float, float], str]:
    """Where the track's bearing is measured, and which reference that is.

    The box centre; but a box cut by the left or right image border has its centre pinned
    near the border while the object leaves the image, so its bearing seems constant: a
    collision course to the monocular test. Its inner edge, the object's side nearest the
    image centre, moves with the object: the bearing is taken there ("left" / "right").
    """
    left, right, _ = sides
    if c is not None:
        u0, v0, u1, v1 = c.bbox
        if left != right:
            return ((u1, 0.5 * (v0 + v1)) if left else (u0, 0.5 * (v0 + v1))), \
                ("left" if left else "right")
    return (float(track.position[0]), float(track.position[1])), "centre"


def contact_of(c: Cluster, f: FrameContext, model: GroundModel) -> GroundContact | None:
    """The ground contact of a cluster: the bottom centre of its box back-projected onto the
    road, the foot moved down by the part of the particles' halo a window reaching below the
    object does not have (:func:`ground_state.foot_halo_shift`)."""
    u0, _, u1, _ = c.bbox
    pose, camera = f.pose, f.camera
    contact = ground_contact(camera, (0.5 * (u0 + u1), c.foot_v - 0.5), pose, model)
    if contact is None:
        return None
    range_m = contact.range_from(pose)
    shift = foot_halo_shift(range_m, f.speed * f.dt, camera.fy, pose.position[2], f.halo_px,
                            f.flow_std_px)
    foot = min(c.foot_v + shift, float(camera.height))
    return ground_contact(camera, (0.5 * (u0 + u1), foot - 0.5), pose, model)


def lowered_contact(c: Cluster, f: FrameContext, model: GroundModel,
                    contact: GroundContact | None, bottom: float) -> GroundContact | None:
    """The ground contact of a cluster whose object reaches down to row ``bottom`` (px, the
    foot cue's), when that is below the contact's row (``contact``, None where the cluster's
    foot is above the horizon: the particles on a head)."""
    u0, _, u1, _ = c.bbox
    pose = f.pose
    if contact is not None:
        range_m = contact.range_from(pose)
        row = c.foot_v + foot_halo_shift(range_m, f.speed * f.dt, f.camera.fy,
                                         pose.position[2], f.halo_px, f.flow_std_px)
        if bottom <= row:
            return contact
    return ground_contact(f.camera, (0.5 * (u0 + u1), bottom - 0.5), pose, model)


def measure_track(track: ImageTrack, f: FrameContext, model: GroundModel) -> TrackMeasurement:
    """What this frame measured of ``track`` (:class:`TrackMeasurement`)."""
    c = track.cluster
    sides = (False, False, False) if c is None else border_sides(
        c, f.camera, BORDER_MARGIN_PX, f.halo_px)
    pixel, ref = bearing_pixel(track, c, sides)
    sighting: Sighting | None = None
    contact: GroundContact | None = None
    if c is not None:
        u0, v0, u1, v1 = c.bbox
        ray = f.odo[2] + bearing(f.camera, (0.5 * (u0 + u1), 0.5 * (v0 + v1)), f.pose)
        cam = to_odometry(f.odo, np.array([f.pose.position[0], f.pose.position[1]]))
        sighting = (f.t, ray, float(cam[0]), float(cam[1]), u1 - u0)
        if track.confirmed and not any(sides):
            contact = contact_of(c, f, model)
    return TrackMeasurement(sides=sides, bearing_ref=ref, bearing=bearing(f.camera, pixel, f.pose),
                            contact=contact, sighting=sighting)
