"""Prior camera motion between two frames from CAN and the PTU: the mean of eq. 9.

The vehicle drives an arc of constant curvature between the two capture times
(speed and yaw rate averaged over the interval); the camera sits on the mount,
turned by the PTU's pan and tilt at each capture time. Body pitch and roll from
road bumps are not on the CAN bus: that is what refinement (section 3) is for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from appliance.config import MountConfig, RefinementConfig
from appliance.messages import SensorSample
from appliance.vision.epipolar import polar_from_translation
from appliance.vision.geometry import (
    FloatArray,
    matrix_to_euler,
    relative_motion,
    rot_z,
    vehicle_from_camera,
)

MIN_TRANSLATION_M = 1e-6   # m, below this the translation has no direction
WIDE_PRIOR_FACTOR = 10.0   # the prior's sigmas grow by this while CAN or the PTU is missing or stale


@dataclass(frozen=True)
class PriorMotion:
    """Mean and standard deviations of the prior p(theta) of eq. 9, and what it is based on.

    R: (3, 3) rotation, ``X_cur = R X_prev + t``; t_m: (3,) translation (m, camera
    frame of the current image; zeros at standstill); theta: (5,) mean
    ``(phi, psi, r_x, r_y, r_z)`` (rad, see ``vision.epipolar``; the polar angles are 0
    at standstill); sigma: (5,) prior standard deviations (rad).
    ``standstill``: the ego vehicle does not move, so no translation direction exists.
    ``wide``: CAN or PTU data were missing or invalid and sigma was widened.
    ``metric``: ``t_m`` has a trustworthy length (the speed was known).
    """

    R: FloatArray
    t_m: FloatArray
    theta: FloatArray
    sigma: FloatArray
    standstill: bool
    wide: bool
    metric: bool


def vehicle_arc(speed_m_s: float, yaw_rate_rad_s: float, dt_s: float) -> FloatArray:
    """4x4 pose of the vehicle after ``dt_s`` on an arc, in the vehicle frame at the start.

    Constant speed (m/s, forward +) and yaw rate (rad/s, CCW +): heading change
    ``dpsi = w dt``, displacement ``(s sin(dpsi)/dpsi, s (1 - cos dpsi)/dpsi)`` with
    ``s = v dt``, written with ``sinc`` so it stays exact for straight driving.
    """
    s = speed_m_s * dt_s
    dpsi = yaw_rate_rad_s * dt_s
    half = 0.5 * dpsi
    T = np.eye(4)
    T[:3, :3] = rot_z(dpsi)
    T[0, 3] = s * float(np.sinc(dpsi / math.pi))
    T[1, 3] = s * math.sin(half) * float(np.sinc(half / math.pi))
    return T


def _finite(*values: float) -> list[float]:
    return [v for v in values if math.isfinite(v)]


def prior_motion(mount: MountConfig, refinement: RefinementConfig, prev: SensorSample,
                 cur: SensorSample, standstill_speed_m_s: float) -> PriorMotion:
    """Prior camera motion from the frame at ``prev.t`` to the frame at ``cur.t``.

    Missing, stale or NaN CAN data (``can_valid`` False or non-finite values) give a
    prior that assumes straight forward driving at the last finite speed (unit
    length, ``metric`` False, when there is none), with every sigma multiplied by
    :data:`WIDE_PRIOR_FACTOR`; an invalid PTU widens it the same way.
    """
    can_ok = prev.can_valid and cur.can_valid
    speeds = _finite(prev.speed_m_s, cur.speed_m_s)
    yaws = _finite(prev.yaw_rate_rad_s, cur.yaw_rate_rad_s)
    can_ok = can_ok and len(speeds) == 2 and len(yaws) == 2
    metric = len(speeds) > 0
    speed = float(np.mean(speeds)) if speeds else 1.0
    yaw_rate = float(np.mean(yaws)) if (yaws and can_ok) else 0.0
    dt = cur.t - prev.t
    dt = dt if math.isfinite(dt) and dt > 0.0 else 0.0
    if not metric:
        dt = 1.0   # only the direction of a unit step forward is used

    ptu_ok = prev.ptu_valid and cur.ptu_valid
    pans = [v if math.isfinite(v) else 0.0 for v in (prev.pan_rad, cur.pan_rad)]
    tilts = [v if math.isfinite(v) else 0.0 for v in (prev.tilt_rad, cur.tilt_rad)]
    ptu_ok = ptu_ok and all(map(math.isfinite, (prev.pan_rad, cur.pan_rad, prev.tilt_rad,
                                                   cur.tilt_rad)))

    position = (mount.x_m, mount.y_m, mount.z_m)
    world_from_prev = vehicle_from_camera(position, mount.pitch_rad, pans[0], tilts[0])
    world_from_cur = vehicle_arc(speed, yaw_rate, dt) @ vehicle_from_camera(
        position, mount.pitch_rad, pans[1], tilts[1])
    R, t = relative_motion(world_from_prev, world_from_cur)

    standstill = metric and (abs(speed) < standstill_speed_m_s
                             or float(np.linalg.norm(t)) < MIN_TRANSLATION_M)
    theta = np.zeros(5)
    theta[2:] = matrix_to_euler(R)
    if not standstill:
        theta[:2] = polar_from_translation(t)
    else:
        t = np.zeros(3)
    sigma = np.array([refinement.sigma_epipole_rad, refinement.sigma_epipole_rad,
                      refinement.sigma_rot_x_rad, refinement.sigma_rot_y_rad,
                      refinement.sigma_rot_z_rad])
    wide = not (can_ok and ptu_ok)
    if wide:
        sigma = sigma * WIDE_PRIOR_FACTOR
    return PriorMotion(R=R, t_m=t, theta=theta, sigma=sigma, standstill=bool(standstill),
                       wide=wide, metric=metric and can_ok)
