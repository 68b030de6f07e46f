"""Does a track's predicted path meet the ego vehicle, and when? (time to collision)

Two cues, combined per track and frame:

* **Ground cue** (primary): the 3-D state (ground_state.py) predicts the object
  at constant velocity over ground and the ego vehicle along the arc of its CAN
  speed and yaw rate (braking to a stop while the driver brakes), over
  ``horizon_s``. The TTC is the first time the object (a disc of the radius its
  box width implies at its range) touches the ego outline widened by
  ``corridor_margin_m`` on each side; the closest approach is the smallest gap
  over the horizon. No contact within the horizon: TTC null.
* **Scale cue** (scale_ttc.py): time until the object reaches the camera's image
  plane, corrected to the front bumper with the 3-D depth where one exists
  (``TTC_bumper = TTC_cam (1 - d / Z)``, d the camera-to-bumper distance).

How they combine (where the ground contact is unreliable: the box touches the
image border, the contact point is beyond ``max_range_m`` or above the horizon):

1. ground contact reliable this frame -> the ground path decides the corridor
   and gives the TTC; the scale cue is not used (on real particle clouds it is
   much noisier than a good ground contact, and the two disagree exactly when a
   cluster mixes object and road particles);
2. no ground contact this frame but a 3-D state updated within ``coast_s``
   -> the coasted state decides the corridor; the TTC is the inverse-variance
   weighted mean of the coasted ground TTC and the bumper-corrected scale TTC,
   so the scale cue takes over smoothly as the coasted variance grows;
3. no usable 3-D state -> scale cue alone. If the track had a 3-D state in the
   last few seconds, its depth is carried on by the expansion rate (dZ/dt = -k Z)
   and gives the lateral miss from bearing and bearing rate; otherwise the
   classic monocular test: constant bearing (predicted bearing change until
   contact below ``bearing_tolerance_rad``) and a bearing inside the corridor as
   seen at the bumper;
4. neither -> TTC and distance null (honestly unknown), no warning from this track.

At standstill nothing changes: back-projection needs no ego motion and the
ego path is a point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import MountConfig

FloatArray = NDArray[np.float64]

STEP_S = 0.05  # s, time resolution of the path prediction


@dataclass(frozen=True)
class PathPrediction:
    """ttc: first contact with the widened outline (s) or None; closest: smallest gap (m, >= 0);
    ahead: at that closest approach the object is in front of the car within the corridor's
    width (the path stays ahead in the lane: a lead car not closing in) rather than beside it."""

    ttc: float | None
    closest: float
    ahead: bool = False


def outline_gap(q: FloatArray, mount: MountConfig, margin: float) -> FloatArray:
    """Distance (m) from points q (..., 2) in a vehicle frame to the ego outline widened
    laterally by ``margin``; 0 inside."""
    dx = np.maximum(np.maximum(-mount.vehicle_rear_m - q[..., 0],
                               q[..., 0] - mount.vehicle_front_m), 0.0)
    dy = np.maximum(np.abs(q[..., 1]) - (0.5 * mount.vehicle_width_m + margin), 0.0)
    return np.hypot(dx, dy)


NEAR_SIDE_SAMPLES = 33   # points along the near side: the gap is within radius / 32 of its minimum


def near_side_gap(position: NDArray[np.floating], radius: float, mount: MountConfig,
                  pan_rad: float = 0.0) -> float:
    """Distance (m) from an object's near side to the ego outline: the segment through its
    ground contact ``position`` (2,) (vehicle frame), ``radius`` m to either side along the
    image row it stands on, i.e. across the camera's optical axis (panned ``pan_rad``, left +):
    the width its box spans at that depth.

    A car crossing at an angle shows the ground contact of its nearest corner at the bottom of
    its box, but the box's centre column is that of its side: the centre's gap is the gap to a
    point beside the corner, 8-12 % too long at 5-35 m on the simulator's crossing car. A car
    straight ahead has its whole near side as far as its centre. Sampled
    (``NEAR_SIDE_SAMPLES``); the gap to a rectangle is convex along a segment."""
    p = np.asarray(position, dtype=np.float64)
    if radius <= 0.0:
        return float(outline_gap(p, mount, 0.0))
    across = np.array([-math.sin(pan_rad), math.cos(pan_rad)])
    s = np.linspace(-1.0, 1.0, NEAR_SIDE_SAMPLES)[:, None]
    return float(np.min(outline_gap(p + s * radius * across, mount, 0.0)))


def predict_path(position: NDArray[np.floating], velocity: NDArray[np.floating], speed: float,
                 yaw_rate: float, mount: MountConfig, margin: float, radius: float,
                 horizon_s: float, accel: float = 0.0, ego_accel: float = 0.0) -> PathPrediction:
    """Object at ``position`` (m) moving at ``velocity`` (m/s over ground), both in the current
    vehicle frame; ego along an arc (speed m/s, yaw rate rad/s); vectorised over time.

    ``accel`` (m/s^2): the object's acceleration along its direction of travel, kept
    constant; a braking object (accel < 0) stops and stays (it does not reverse).
    ``ego_accel`` (m/s^2): the ego's own, the same way (a car braking to a stop drives no
    farther than its stopping distance), along the same arc (curvature yaw rate / speed)."""
    tau = np.arange(0.0, horizon_s + 1e-9, STEP_S)
    v = np.asarray(velocity, dtype=np.float64)
    v_abs = float(np.hypot(v[0], v[1]))
    if accel != 0.0 and v_abs > 1e-6:
        t_move = min(-v_abs / accel, horizon_s) if accel < 0.0 else horizon_s
        tm = np.minimum(tau, t_move)
        travel = v_abs * tm + 0.5 * accel * tm * tm  # m along the direction of travel
        along = v / v_abs
        px0 = position[0] + along[0] * travel
        py0 = position[1] + along[1] * travel
    else:
        px0 = position[0] + v[0] * tau
        py0 = position[1] + v[1] * tau
    if ego_accel < 0.0 and speed > 0.0:
        te = np.minimum(tau, -speed / ego_accel)
        s_ego = speed * te + 0.5 * ego_accel * te * te   # m driven, the arc's length
        k = yaw_rate / speed
        psi = k * s_ego
        if abs(k) > 1e-6:
            ex, ey = np.sin(psi) / k, (1.0 - np.cos(psi)) / k
        else:
            ex, ey = s_ego, np.zeros_like(tau)
    else:
        psi = yaw_rate * tau
        if abs(yaw_rate) > 1e-4:
            ex = speed * np.sin(psi) / yaw_rate
            ey = speed * (1.0 - np.cos(psi)) / yaw_rate
        else:
            ex, ey = speed * tau, np.zeros_like(tau)
    px = px0 - ex
    py = py0 - ey
    c, s = np.cos(psi), np.sin(psi)
    q = np.stack([c * px + s * py, -s * px + c * py], axis=-1)
    gap = outline_gap(q, mount, margin) - radius
    hit = np.flatnonzero(gap <= 0.0)
    ttc = float(tau[hit[0]]) if len(hit) else None
    k = int(np.argmin(gap))
    ahead = bool(q[k, 0] > mount.vehicle_front_m
                 and abs(q[k, 1]) <= 0.5 * mount.vehicle_width_m + margin + radius)
    return PathPrediction(ttc=ttc, closest=float(max(gap[k], 0.0)), ahead=ahead)


def ground_ttc_std(position: NDArray[np.floating], P: NDArray[np.floating], ttc: float,
                   speed: float, velocity: NDArray[np.floating]) -> float:
    """Approximate std (s) of a ground-path TTC: the longitudinal position and velocity
    uncertainty divided by the closing speed."""
    closing = max(speed - float(velocity[0]), 0.5)
    var = P[0, 0] + ttc * ttc * P[2, 2] + 2.0 * ttc * P[0, 2]
    return math.sqrt(max(var, 1e-6)) / closing


def path_expansion(depth_m: float, axis: NDArray[np.floating], velocity: NDArray[np.floating],
                   speed: float) -> float | None:
    """The expansion rate k (1/s) the image of an object at camera depth ``depth_m`` shows when
    it moves over ground at ``velocity`` (m/s, vehicle x, y) and the ego vehicle drives along x
    at ``speed``: its closing speed along the camera's axis on the road (``axis``, unit (2,))
    over its depth, k = c / Z (collision-course.md, ``TTC ~ dt * s / ds``). None within half a
    metre of the camera plane."""
    if depth_m <= 0.5:
        return None
    closing = speed * float(axis[0]) - float(np.dot(axis, velocity))
    return closing / depth_m


def contact_depth_per_px(range_m: float, fy: float, camera_height_m: float) -> float:
    """Metres of depth one image row of a ground contact spans at ``range_m`` (flat road,
    camera ``camera_height_m`` above it): r^2 / (fy h)."""
    return range_m * range_m / (fy * max(camera_height_m, 1e-3))


def fuse(a: tuple[float, float] | None, b: tuple[float, float] | None
         ) -> tuple[float, float] | None:
    """Inverse-variance weighted mean of two (value, std) estimates; either may be None."""
    if a is None:
        return b
    if b is None:
        return a
    wa, wb = 1.0 / (a[1] ** 2), 1.0 / (b[1] ** 2)
    return ((wa * a[0] + wb * b[0]) / (wa + wb), math.sqrt(1.0 / (wa + wb)))


def bumper_ttc(ttc_cam: tuple[float, float], depth_m: float | None, mount: MountConfig
               ) -> tuple[float, float]:
    """Scale TTC to the camera plane -> to the front bumper, when the depth Z (m, along the
    vehicle x axis from the camera) is known; unchanged otherwise."""
    d = mount.vehicle_front_m - mount.x_m
    if depth_m is None or depth_m <= d + 0.1:
        return ttc_cam
    f = 1.0 - d / depth_m
    return (ttc_cam[0] * f, ttc_cam[1] * f)


def constant_bearing_course(bearing: float, bearing_rate: float, ttc: float,
                            mount: MountConfig, margin: float, tolerance: float) -> bool:
    """Monocular collision-course test without a range: the bearing hardly changes until
    contact and lies inside the corridor seen from the camera at the bumper."""
    d = max(mount.vehicle_front_m - mount.x_m, 0.5)
    half = math.atan2(0.5 * mount.vehicle_width_m + margin, d)
    return abs(bearing_rate * ttc) <= tolerance and abs(bearing) <= half


def scale_lateral_miss(depth: float, bearing: float, bearing_rate: float, k: float,
                       ttc: float, mount: MountConfig) -> float:
    """Lateral position (m, vehicle y) at contact of an object without a ground contact but
    with a depth Z carried on by the scale cue: y = y_cam + Z tan(b), and its rate
    dy/dt = dZ/dt tan(b) + Z db/dt / cos^2(b) with dZ/dt = -k Z (k the expansion rate, 1/s)."""
    tb = math.tan(bearing)
    y = mount.y_m + depth * tb
    ydot = -k * depth * tb + depth * bearing_rate / math.cos(bearing) ** 2
    return y + ydot * ttc


def object_radius(box_width_px: float, range_m: float, fx: float) -> float:
    """Half the object's lateral extent (m) from its box width at its range, in [0.2, 2.5] m."""
    return float(min(max(0.5 * box_width_px * range_m / fx, 0.2), 2.5))


def significant_acceleration(velocity: NDArray[np.floating], acceleration: NDArray[np.floating],
                             P: NDArray[np.floating], sigmas: float) -> float:
    """The acceleration (m/s^2) along the direction of ``velocity`` (2,) when it is at least
    ``sigmas`` times its std (``P`` (6, 6) of ``[x, y, vx, vy, ax, ay]``), 0 (predicted at
    constant velocity) below ``sigmas - 1`` std, and scaled linearly from 0 to 1 in between:
    an estimate that hovers around the threshold would otherwise switch the TTC between the
    two predictions (1.6 -> 2.55 s in one frame on a braking car, dropping its level 2). 0 for
    a state without acceleration (P (4, 4)) or standing still."""
    P = np.asarray(P, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    speed = float(np.hypot(v[0], v[1]))
    if P.shape[0] < 6 or speed < 1e-6:
        return 0.0
    d = v / speed
    a = float(d @ np.asarray(acceleration, dtype=np.float64))
    std = math.sqrt(max(float(d @ P[4:6, 4:6] @ d), 0.0))
    if std <= 0.0:
        return a
    return a * min(max(abs(a) / std - (sigmas - 1.0), 0.0), 1.0)


def significant_speed(velocity: NDArray[np.floating], P: NDArray[np.floating],
                      sigmas: float) -> float:
    """The speed over ground (m/s) the object moves at least, at ``sigmas`` std: its estimate
    less ``sigmas`` times the std of the velocity along its direction (``P`` (4, 4) of
    ``[x, y, vx, vy]``), 0 at the least. A pedestrian's 3-D state a few contacts after its
    range jumped can read 6 m/s with a std of 2 m/s: no car or cyclist."""
    v = np.asarray(velocity, dtype=np.float64)
    speed = float(np.hypot(v[0], v[1]))
    if speed == 0.0:
        return 0.0
    u = v / speed
    var = float(u @ np.asarray(P, dtype=np.float64)[2:4, 2:4] @ u)
    return max(0.0, speed - sigmas * float(np.sqrt(max(var, 0.0))))


def significant_velocity(velocity: NDArray[np.floating], P: NDArray[np.floating],
                         sigmas: float) -> FloatArray:
    """Velocity over ground (2,) m/s with each component (vehicle x, y) whose magnitude is
    below ``sigmas`` times its std set to 0 (``P`` (4, 4) of ``[x, y, vx, vy]``); where the
    longitudinal one is, the lateral one is the one it has given that, value and std (the
    Gaussian conditional on ``vx = 0``).

    A range rate is much less certain than a bearing rate: with a ground contact a few
    pixels noisy, the longitudinal velocity over ground of a crossing pedestrian 20 m ahead
    has a std of about 1 m/s for a second and more. Predicting with such a noise value as
    if it were known turns a pedestrian who passes 1 m in front of the car into one who
    meets it (it seems to walk towards the car); a component that is not distinguishable
    from 0 is predicted as 0, the static world's value. The range rate's error lies along
    the line of sight, so it also spreads into the lateral velocity, by the tangent of the
    bearing, while the velocity across the line of sight is known to a tenth of a metre per
    second: 40 m ahead and 16 m to the side, a cyclist riding into the path at 4.6 m/s whose
    range rate is 4.8 m/s off reads 2.6 +- 1.9 m/s laterally. Given ``vx = 0``, the lateral
    velocity is the one that moves the object across the line of sight as measured (4.4 m/s,
    to that tenth); kept as it was, with ``vx`` set to 0, it would move it across the line
    of sight 1.9 m/s slower than measured and the cyclist would miss the car by metres.
    ``sigmas`` 0: unchanged.
    """
    v = np.asarray(velocity, dtype=np.float64).copy()
    if sigmas <= 0.0:
        return v
    Pv = np.asarray(P, dtype=np.float64)[2:4, 2:4]
    var_x, cov_xy, var_y = float(Pv[0, 0]), float(Pv[0, 1]), float(Pv[1, 1])
    if abs(v[0]) < sigmas * math.sqrt(max(var_x, 0.0)):
        if var_x > 0.0:
            var_y -= cov_xy * cov_xy / var_x
            v[1] -= cov_xy / var_x * v[0]
        v[0] = 0.0
    if abs(v[1]) < sigmas * math.sqrt(max(var_y, 0.0)):
        v[1] = 0.0
    return v
