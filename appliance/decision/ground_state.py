"""3-D state of a track on the road plane, in the vehicle frame (ISO 8855: x fwd, y left).

What the paper lacks and the model-based tracking fragment motivates: a track's
ground contact point (bottom centre of its box) is back-projected onto the road
plane with the camera height, the refined pitch and the PTU angles; a Kalman
filter estimates the object's position and its velocity *over ground* in the
current vehicle frame, with the ego motion from CAN (speed, yaw rate) removed in
the prediction step.

Robustness, where real particle clouds need it: a contact further than
``gate_sigmas`` from the prediction is skipped (a stray particle row), five in a
row restart the state; where the object is known to reach below its cluster, a
contact farther than predicted counts less (:func:`one_sided`); the filter has a
fading memory (``memory_s``, filterpy's ``alpha``) so a state started on a wrong
association recovers; a new state takes its velocity across the line of sight
from the track's bearing rate (:func:`velocity_prior`) instead of assuming 0, so a
crossing car has the right path from its first frames.

Refined pitch: the body pitch b (rad, nose down positive) that CAN cannot see
(road bumps) is the accumulated difference between the refined and the prior
inter-frame rotations, mapped from camera axes to the vehicle's y axis; it decays
towards zero with ``PITCH_DECAY_S`` so that it cannot drift. The camera's pitch
for back-projection is then ``mount.pitch_rad + b`` with pan and tilt from the PTU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import predict, update
from numpy.typing import NDArray

from appliance.config import MountConfig
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import PinholeCamera, vehicle_from_camera_rotation

FloatArray = NDArray[np.float64]

# a ray must point at least this far below the horizon (dz per unit length) to hit the road
MIN_DOWN = 1e-4
PITCH_DECAY_S = 1.0  # s, time constant pulling the refined body pitch back to zero


@dataclass(frozen=True)
class GroundModel:
    """Parameters of the ground contact and the 3-D filter. ``contact_std_px`` and
    ``max_range_m`` come from the ground cue's table (``[cue.ground]``); the rest are the
    filter's own constants."""

    contact_std_px: float = 3.0          # px, std of the contact in the image, u and v
    max_range_m: float = 60.0            # m, a contact further from the camera is not used
    pitch_std_rad: float = 0.003         # rad, std of the refined camera pitch in the back-projection
    process_accel_m_s2: float = 1.0      # m/s^2, process noise of the velocity over ground
    accel_std_m_s2: float = 3.0          # m/s^2, spread of the acceleration over ground (Singer model)
    accel_time_constant_s: float = 2.0   # s, how long such an acceleration lasts
    accel_min_speed_m_s: float = 5.0     # m/s, slower objects (pedestrians) get no acceleration
    initial_velocity_std_m_s: float = 8.0  # m/s, initial std of the velocity over ground
    gate_sigmas: float = 3.5             # a contact further than this (Mahalanobis) is an outlier
    memory_s: float = 1.0                # s, fading memory: older contacts count less (0: none)
    far_factor: float = 3.0              # a contact reading farther than predicted: its range std
                                         #   this many times larger (feet found too high)


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is and how it looks, for back-projection.

    position: camera centre in the vehicle frame (m); pitch: mount pitch plus the
    refined body pitch (rad, positive looks down); pan/tilt: PTU (rad).
    """

    position: tuple[float, float, float]
    pitch: float
    pan: float
    tilt: float

    def rotation(self) -> FloatArray:
        """Vehicle-from-camera rotation (3, 3)."""
        return vehicle_from_camera_rotation(self.pitch, self.pan, self.tilt)


def camera_pose(mount: MountConfig, body_pitch: float, sensors: SensorSample) -> CameraPose:
    return CameraPose((mount.x_m, mount.y_m, mount.z_m), mount.pitch_rad + body_pitch,
                      sensors.pan_rad, sensors.tilt_rad)


def ground_in_camera(pose: CameraPose, position: NDArray[np.floating]) -> FloatArray:
    """A road point ``position`` (x, y) m in the vehicle frame, in the camera frame (3,) m (z: depth)."""
    p = np.array([float(position[0]), float(position[1]), 0.0])
    return np.asarray(pose.rotation().T @ (p - np.asarray(pose.position)))


def update_body_pitch(b: float, ego: EgoMotion, pose_prev: CameraPose, dt: float) -> float:
    """Body pitch (rad, nose down +) after this frame's refined rotation.

    The refined minus the prior rotation (camera axes, point rotation) is the
    part CAN and the PTU did not predict; rotated into the vehicle frame, its y
    component (with a minus: a nose-down body rotation shows up as +r_x for a
    level camera) is the body pitch increment. Not integrated when the
    refinement kept its prior (``confident`` False). Decays with
    ``PITCH_DECAY_S``.
    """
    decay = math.exp(-max(dt, 0.0) / PITCH_DECAY_S)
    if not ego.confident:
        return b * decay
    d = np.asarray(ego.rotation, dtype=np.float64) - np.asarray(ego.prior_rotation, float)
    if not np.all(np.isfinite(d)):
        return b * decay
    inc = -float((pose_prev.rotation() @ d)[1])
    return (b + inc) * decay


def back_project(camera: PinholeCamera, uv: NDArray[np.floating], pose: CameraPose) -> FloatArray:
    """Image pixels (N, 2) -> points (N, 2) (x, y) on the road plane z = 0, vehicle frame, m.

    Rows whose ray does not point below the horizon are NaN.
    """
    rays = camera.rays(np.asarray(uv, dtype=np.float64).reshape(-1, 2))
    d = rays @ pose.rotation().T
    out = np.full((len(d), 2), np.nan)
    down = d[:, 2] < -MIN_DOWN
    lam = -pose.position[2] / d[down, 2]
    out[down, 0] = pose.position[0] + lam * d[down, 0]
    out[down, 1] = pose.position[1] + lam * d[down, 1]
    return out


def bearing(camera: PinholeCamera, uv: tuple[float, float], pose: CameraPose) -> float:
    """Azimuth (rad, CCW/left positive) of pixel ``uv`` seen from the camera, vehicle frame."""
    d = pose.rotation() @ camera.rays(np.array([uv]))[0]
    return float(math.atan2(d[1], d[0]))


@dataclass(frozen=True)
class GroundContact:
    """A back-projected ground contact: position (2,) m and its covariance (2, 2) m^2."""

    z: FloatArray
    R: FloatArray

    @property
    def range_m(self) -> float:
        return float(np.hypot(self.z[0], self.z[1]))

    def range_from(self, pose: CameraPose) -> float:
        """Distance (m) on the road from below the camera of ``pose`` to the contact."""
        return math.hypot(self.z[0] - pose.position[0], self.z[1] - pose.position[1])


def foot_halo_shift(range_m: float, travel_m: float, fy: float, height_m: float, halo_px: float,
                    sigma_px: float) -> float:
    """Rows (px, >= 0) to move a cluster's foot down: the part of the particles' halo that a
    window reaching below the object does not have.

    The cluster's foot is its lowest moving particles less ``halo_px`` (half the LK window),
    as on its other sides, where a window centred beside the object still follows its edge.
    Below the object is road: its own flow there, ``L = fy h d / Z^2`` px per frame (a road
    point at range Z, camera height h, the ego's travel d per frame), is static, and a window
    holding it looks static once L is long against the flow noise ``sigma_px``. So the halo
    below the feet is ``halo_px exp(-L^2 / 2 sigma^2)`` and the foot moves down by the rest.
    On the simulator (10 m/s) the foot was 3-5 px above the truth box's bottom at 10-30 m
    and within a pixel beyond 30 m, where L < 0.4 px."""
    if not (range_m > 0.0 and travel_m > 0.0 and sigma_px > 0.0):
        return 0.0
    L = fy * height_m * travel_m / (range_m * range_m)
    return float(halo_px * -math.expm1(-0.5 * (L / sigma_px) ** 2))


def ground_contact(camera: PinholeCamera, uv: tuple[float, float], pose: CameraPose,
                   cfg: GroundModel) -> GroundContact | None:
    """The road point under pixel ``uv`` with its covariance, or None when it is unusable.

    The covariance propagates ``contact_std_px`` in u and v and ``pitch_std_rad``
    through the back-projection (numerical Jacobian). None when the pixel is at or
    above the horizon, or the point is further than ``max_range_m`` from the camera.
    """
    du, dp = 0.5, 1e-4
    pts = np.array([uv, (uv[0] + du, uv[1]), (uv[0], uv[1] + du)])
    xy = back_project(camera, pts, pose)
    pose_p = CameraPose(pose.position, pose.pitch + dp, pose.pan, pose.tilt)
    xy_p = back_project(camera, pts[:1], pose_p)
    if not (np.all(np.isfinite(xy)) and np.all(np.isfinite(xy_p))):
        return None
    z = xy[0]
    if math.hypot(z[0] - pose.position[0], z[1] - pose.position[1]) > cfg.max_range_m:
        return None
    J = np.column_stack([(xy[1] - z) / du, (xy[2] - z) / du, (xy_p[0] - z) / dp])
    S = np.diag([cfg.contact_std_px ** 2, cfg.contact_std_px ** 2, cfg.pitch_std_rad ** 2])
    R = J @ S @ J.T + np.eye(2) * 1e-4
    return GroundContact(z=z, R=R)


# ----------------------------------------------------------------- 3-D filter


@dataclass(frozen=True)
class GroundTrack:
    """State ``[x, y, vx, vy]`` (m, m/s): position in the current vehicle frame and the
    object's velocity over ground expressed in it; P (4, 4). With the acceleration model
    (``accel_std_m_s2`` > 0) the state is ``[x, y, vx, vy, ax, ay]`` and P (6, 6): the
    acceleration over ground too (m/s^2). t_update: time of the last ground contact (s);
    updates: how many contacts it has taken; rejected: outliers in a row. P_measured: P
    after the last measurement (a contact, a velocity or bearing update); a prediction leaves
    it as it was, so it tells how well the state was known when last seen (None: P)."""

    x: FloatArray
    P: FloatArray
    t_update: float
    updates: int
    rejected: int = 0
    P_measured: FloatArray | None = None

    @property
    def measured_covariance(self) -> FloatArray:
        """P after the last measurement (``P_measured``), P itself where none is recorded."""
        return self.P if self.P_measured is None else self.P_measured

    @property
    def position(self) -> FloatArray:
        return self.x[:2]

    @property
    def velocity(self) -> FloatArray:
        return self.x[2:4]

    @property
    def acceleration(self) -> FloatArray:
        """Acceleration over ground (2,) m/s^2; 0 without the acceleration model."""
        return self.x[4:6] if len(self.x) == 6 else np.zeros(2)

    @property
    def speed(self) -> float:
        """Speed over ground (m/s)."""
        return float(np.hypot(self.x[2], self.x[3]))


def road_axis(pose: CameraPose) -> FloatArray | None:
    """Unit direction (2,) of the camera's optical axis on the road (vehicle frame); None
    when the camera looks straight down or up."""
    axis = pose.rotation()[:2, 2]
    n = float(np.hypot(axis[0], axis[1]))
    return None if n < 1e-6 else axis / n


def h_position(n: int) -> FloatArray:
    """Measurement matrix (2, n) of the position."""
    return np.hstack([np.eye(2), np.zeros((2, n - 2))])



def ground_init(contact: GroundContact, t: float, cfg: GroundModel,
                prior: tuple[FloatArray, FloatArray] | None = None) -> GroundTrack:
    """A new 3-D state at ``contact``; velocity from ``prior`` (mean (2,), covariance
    (2, 2), m/s over ground) or 0 +- ``initial_velocity_std_m_s``; with the acceleration
    model, acceleration 0 +- ``accel_std_m_s2``."""
    n = 6 if cfg.accel_std_m_s2 > 0.0 else 4
    P = np.zeros((n, n))
    P[:2, :2] = contact.R
    v = np.zeros(2)
    P[2:4, 2:4] = np.eye(2) * cfg.initial_velocity_std_m_s ** 2
    if prior is not None and np.all(np.isfinite(prior[0])) and np.all(np.isfinite(prior[1])):
        v, P[2:4, 2:4] = np.asarray(prior[0], float), np.asarray(prior[1], float)
    if n == 6:
        P[4:, 4:] = np.eye(2) * cfg.accel_std_m_s2 ** 2
    return GroundTrack(x=np.concatenate([contact.z, v, np.zeros(n - 4)]), P=P, t_update=t,
                       updates=1, P_measured=P)


@dataclass(frozen=True)
class LineOfSight:
    """The line of sight from the camera to ``z`` (vehicle frame): range r (m), unit
    ``radial`` and ``tangent`` (2,), and ``crossing`` (m/s): the velocity across it that the
    bearing rate ``rate`` says the object has over ground, ``r rate`` less the part a
    static point there has (ego speed and yaw)."""

    r: float
    radial: FloatArray
    tangent: FloatArray
    crossing: float


def line_of_sight(z: FloatArray, bearing_rate: float, speed: float, yaw_rate: float,
                  camera_xy: tuple[float, float]) -> LineOfSight | None:
    """See :class:`LineOfSight`; None when ``z`` is at the camera (r < 1 mm)."""
    d = np.asarray(z, float) - np.asarray(camera_xy, float)
    r = float(np.hypot(d[0], d[1]))
    if r < 1e-3:
        return None
    radial = d / r
    tangent = np.array([-radial[1], radial[0]])
    static_rel = np.array([-speed + yaw_rate * z[1], -yaw_rate * z[0]])
    return LineOfSight(r, radial, tangent, r * bearing_rate - float(static_rel @ tangent))


def velocity_prior(z: FloatArray, bearing_rate: float, speed: float, yaw_rate: float,
                   camera_xy: tuple[float, float], cfg: GroundModel,
                   bearing_rate_std: float = 0.01) -> tuple[FloatArray, FloatArray]:
    """Velocity over ground (mean, covariance) of an object at ``z`` (m, vehicle frame) whose
    bearing from the camera turns at ``bearing_rate`` (rad/s, vehicle frame).

    The bearing rate fixes the relative velocity across the line of sight (r times the
    rate, precise: it comes from the tracked flow); the part a static point would have
    (ego speed and yaw) is removed. Along the line of sight nothing is known yet: 0 over
    ground with ``initial_velocity_std_m_s``. A crossing car starts with most of its
    speed instead of 0, so its path is right from the first frames.
    """
    los = line_of_sight(z, bearing_rate, speed, yaw_rate, camera_xy)
    if los is None:
        return np.zeros(2), np.eye(2) * cfg.initial_velocity_std_m_s ** 2
    mean = los.crossing * los.tangent
    sd_t = max(los.r * bearing_rate_std, 0.3)
    cov = (np.outer(los.tangent, los.tangent) * sd_t ** 2
           + np.outer(los.radial, los.radial) * cfg.initial_velocity_std_m_s ** 2)
    return mean, cov


def velocity_update(g: GroundTrack, direction: FloatArray, value: float, std: float
                    ) -> GroundTrack:
    """Kalman update of the velocity component along the unit ``direction`` (2,) with a
    measurement ``value`` +- ``std`` m/s; position, time and counts unchanged."""
    H = np.concatenate([np.zeros(2), direction, np.zeros(len(g.x) - 4)]).reshape(1, -1)
    x, P = update(g.x, g.P, np.array([value]), np.array([[std ** 2]]), H)
    return replace(g, x=x, P=P, P_measured=P)


def range_rate_update(g: GroundTrack, rate_1_s: float, rate_var: float, pose: CameraPose,
                      speed: float, gate_sigmas: float = math.inf) -> GroundTrack:
    """Kalman update of the velocity along the camera axis (on the road) from the object's image
    expansion rate ``rate_1_s`` (1/s, variance ``rate_var``): an object at depth Z closing at
    c expands at c / Z, so its velocity over ground along the axis d is ``v d_x - rate Z``
    (the ego vehicle drives along x at ``speed``). Z is the state's own depth; its error only
    scales the measurement, which is small where the object does not close on its own. A
    rate further than ``gate_sigmas`` (innovation std) from the state's is skipped."""
    z = ground_in_camera(pose, g.position)[2]
    d = road_axis(pose)
    if z <= 0.5 or d is None or not math.isfinite(rate_1_s) or rate_var <= 0.0:
        return g
    value, var = speed * float(d[0]) - rate_1_s * z, rate_var * z * z
    innovation = value - float(d @ g.velocity)
    if innovation ** 2 > gate_sigmas ** 2 * (float(d @ g.P[2:4, 2:4] @ d) + var):
        return g
    return velocity_update(g, d, value, math.sqrt(var))


def bearing_rate_update(g: GroundTrack, bearing_rate: float, speed: float, yaw_rate: float,
                        camera_xy: tuple[float, float], rate_std: float) -> GroundTrack:
    """Update the velocity over ground across the line of sight with a measured bearing rate
    (rad/s, vehicle frame, ``rate_std`` its std).

    The relative velocity across the line of sight is r times the bearing rate; removing the
    part a static point has (ego speed and yaw, as in :func:`velocity_prior`) leaves a linear
    measurement of the object's velocity: ``tangent . v = r rate - tangent . static_rel``
    with std ``r rate_std``. The range r and the directions come from the current state.
    """
    if not math.isfinite(bearing_rate):
        return g
    los = line_of_sight(g.x[:2], bearing_rate, speed, yaw_rate, camera_xy)
    if los is None:
        return g
    return velocity_update(g, los.tangent, los.crossing, los.r * rate_std)


def bearing_innovation(g: GroundTrack, azimuth: float, camera_xy: tuple[float, float],
                       std_rad: float) -> tuple[float, float]:
    """The innovation of a measured ``azimuth`` (rad, vehicle frame, seen from the camera at
    ``camera_xy``; ``std_rad`` its std) against the state: how far (m) the state's position
    lies across the ray, negated, and that distance's variance (m^2: the state's across-ray
    position variance and the measurement's at the state's range)."""
    c = np.asarray(camera_xy, dtype=np.float64)
    r = float(np.hypot(*(g.x[:2] - c)))
    n = np.array([-math.sin(azimuth), math.cos(azimuth)])
    S = float(n @ g.P[:2, :2] @ n) + (r * std_rad) ** 2
    return -float(n @ (g.x[:2] - c)), S


def bearing_update(g: GroundTrack, azimuth: float, camera_xy: tuple[float, float],
                   std_rad: float) -> GroundTrack:
    """Update of the position and velocity across the line of sight with a measured
    ``azimuth`` (rad, vehicle frame, seen from the camera at ``camera_xy``; ``std_rad`` its
    std): the position's component across the ray, ``n . (p - c)``, is measured as 0 +- r std
    (r the state's range). Only the across-ray components are corrected (a Kalman gain
    restricted to them, Joseph form): a bearing says nothing about the range, and through the
    state's correlations a full update moved a coasted range by metres. Time and counts are
    unchanged (it is no ground contact). Used for a hidden object whose head shows."""
    c = np.asarray(camera_xy, dtype=np.float64)
    r = float(np.hypot(*(g.x[:2] - c)))
    if not math.isfinite(azimuth) or r < 0.5 or std_rad <= 0.0:
        return g
    n = np.array([-math.sin(azimuth), math.cos(azimuth)])
    T = np.zeros((2, len(g.x)))
    T[0, :2], T[1, 2:4] = n, n                 # across-ray position and velocity
    H = T[:1]
    innovation, S = bearing_innovation(g, azimuth, camera_xy, std_rad)
    K = T.T @ (T @ g.P @ H.T) / S              # (n, 1): the gain of the across-ray components
    x = g.x + K[:, 0] * innovation
    A = np.eye(len(g.x)) - K @ H
    P = A @ g.P @ A.T + (r * std_rad) ** 2 * (K @ K.T)
    return replace(g, x=x, P=P, P_measured=P)


def ego_step(speed: float, yaw_rate: float, dt: float) -> tuple[FloatArray, FloatArray]:
    """(Rt, d): the old-to-new frame rotation Rz(-dpsi) (2, 2) and the ego displacement d
    (2,) m in the old frame, for a circular arc at ``speed`` m/s and ``yaw_rate`` rad/s."""
    dpsi = yaw_rate * dt
    c, s = math.cos(dpsi), math.sin(dpsi)
    Rt = np.array([[c, s], [-s, c]])
    d = speed * dt * np.array([math.cos(0.5 * dpsi), math.sin(0.5 * dpsi)])
    return Rt, d


def ground_predict(g: GroundTrack, dt: float, sensors: SensorSample, cfg: GroundModel,
                   steady: bool = False) -> GroundTrack:
    """Move the state by ``dt`` s: the object at constant velocity over ground, the frame with
    the ego vehicle (CAN speed and yaw rate): p' = Rt (p + v dt - d), v' = Rt v.

    With the acceleration model (6 states) the acceleration over ground is a first-order
    Markov process (Singer): p' = Rt (p + v dt + a dt^2 / 2 - d), v' = Rt (v + a dt),
    a' = Rt phi a with phi = exp(-dt / accel_time_constant_s), driven by white noise of
    variance accel_std^2 (1 - phi^2) so that the acceleration's spread stays accel_std. The
    velocity keeps its own process noise (``process_accel_m_s2``), so a walking pedestrian
    is followed as before and the acceleration takes up what lasts: a braking car.

    ``steady``: the state has had no ground contact since the frame before (coasting: hidden,
    or its contact unusable), or it moves slower than ``accel_min_speed_m_s``; it forgets its
    acceleration (0 +- accel_std, uncorrelated) and moves at constant velocity. An
    acceleration cannot be followed without contacts, and integrated over a second of
    coasting a small one moves a pedestrian off the corridor."""
    if dt <= 0.0:
        return g
    # the acceleration of a slow object (a pedestrian) is not estimated: it would mostly be
    # its ground contacts' noise, and make its velocity noisier
    steady = steady or g.speed < cfg.accel_min_speed_m_s
    if steady and len(g.x) == 6:
        x0, P0 = g.x.copy(), g.P.copy()
        x0[4:] = 0.0
        P0[4:, :] = 0.0
        P0[:, 4:] = 0.0
        P0[4:, 4:] = np.eye(2) * cfg.accel_std_m_s2 ** 2
        g = replace(g, x=x0, P=P0)
    speed = sensors.speed_m_s if math.isfinite(sensors.speed_m_s) else 0.0
    yaw = sensors.yaw_rate_rad_s if math.isfinite(sensors.yaw_rate_rad_s) else 0.0
    Rt, d = ego_step(speed, yaw, dt)
    n = len(g.x)
    F = np.zeros((n, n))
    F[:2, :2] = Rt
    F[:2, 2:4] = Rt * dt
    F[2:4, 2:4] = Rt
    B = np.vstack([-Rt, np.zeros((n - 2, 2))])
    q = Q_discrete_white_noise(dim=2, dt=dt, var=cfg.process_accel_m_s2 ** 2)
    Q = np.zeros((n, n))
    for i in range(2):
        Q[np.ix_([i, i + 2], [i, i + 2])] = q
    if n == 6 and not steady:
        phi = math.exp(-dt / cfg.accel_time_constant_s) if cfg.accel_time_constant_s > 0.0 \
            else 0.0
        F[:2, 4:] = Rt * (0.5 * dt * dt)
        F[2:4, 4:] = Rt * dt
        F[4:, 4:] = Rt * phi
        Q[4:, 4:] += np.eye(2) * cfg.accel_std_m_s2 ** 2 * (1.0 - phi * phi)
    elif n == 6:
        F[4:, 4:] = np.eye(2)  # forgotten above: 0 +- accel_std, kept so until a contact
    if not sensors.can_valid:
        # ego motion unknown: the displacement may be wrong by several m/s
        Q[:2, :2] += np.eye(2) * (3.0 * dt) ** 2
    # fading memory (filterpy's alpha): old contacts lose weight with memory_s, so a state
    # polluted by a wrong association or a range bias that changes with range recovers
    alpha = math.exp(0.5 * dt / cfg.memory_s) if cfg.memory_s > 0.0 else 1.0
    x, P = predict(g.x, g.P, F, Q, u=d, B=B, alpha=alpha)
    return replace(g, x=x, P=P)


def one_sided(g: GroundTrack, contact: GroundContact, factor: float) -> GroundContact:
    """``contact`` with its range std ``factor`` times larger where it reads farther than the
    predicted position. Its range error is one-sided: the foot of an object is found too high
    (thin legs in motion lose their flow, the particles gather on the hips) and reads too far,
    but never below the feet, where the road's flow starts. The range direction is the
    principal axis of the contact's covariance (the back-projected row's error)."""
    if factor <= 1.0:
        return contact
    lam, vecs = np.linalg.eigh(contact.R)
    axis = vecs[:, 1]
    if float(axis @ contact.z) < 0.0:
        axis = -axis
    if float(axis @ (contact.z - g.x[:2])) <= 0.0:
        return contact
    wider = (factor ** 2 - 1.0) * lam[1] * np.outer(axis, axis)
    return GroundContact(z=contact.z, R=contact.R + wider)


def ground_update(g: GroundTrack, contact: GroundContact, t: float) -> GroundTrack:
    x, P = update(g.x, g.P, contact.z, contact.R, h_position(len(g.x)))
    return replace(g, x=x, P=P, t_update=t, updates=g.updates + 1, rejected=0, P_measured=P)


def innovation_sigmas(g: GroundTrack, contact: GroundContact) -> float:
    """Mahalanobis distance of a contact from the predicted position (in std)."""
    y = contact.z - g.x[:2]
    S = g.P[:2, :2] + contact.R
    return float(math.sqrt(max(float(y @ np.linalg.solve(S, y)), 0.0)))


def ground_absorb(g: GroundTrack | None, contact: GroundContact, t: float, cfg: GroundModel,
                  prior: tuple[FloatArray, FloatArray] | None = None,
                  above_feet: bool = False, far_factor: float | None = None) -> GroundTrack:
    """Start, update or (outlier) skip: a contact further than ``gate_sigmas`` from the
    prediction is skipped once the state has 3 contacts; 5 outliers in a row restart it
    (the object was lost and found elsewhere, or the state went wrong). ``above_feet``: the
    object is known to reach below its cluster, a contact reading farther than predicted
    counts ``far_factor`` (None: the model's) times its range std (:func:`one_sided`)."""
    if g is None:
        return ground_init(contact, t, cfg, prior)
    if above_feet:
        contact = one_sided(g, contact, cfg.far_factor if far_factor is None else far_factor)
    if g.updates >= 3 and innovation_sigmas(g, contact) > cfg.gate_sigmas:
        if g.rejected + 1 >= 5:
            return ground_init(contact, t, cfg, prior)
        return replace(g, rejected=g.rejected + 1)
    return ground_update(g, contact, t)
