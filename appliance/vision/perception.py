"""The vision core's per-frame step: flow, refinement (section 3) and detection (section 2).

``perceive(state, frame, sensors, prob_map, cfg, camera) -> (state, ego, particles)``
is a pure function: time comes in with the frame, randomness from a generator
seeded by ``(seed, frame count)``, so the same inputs always give the same outputs
and a replay reproduces a drive exactly.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.errors import UsageError
from appliance.messages import EgoMotion, Frame, ParticleSet, ProbabilityMap, SensorSample
from appliance.vision.baseline import HISTORY, PastFrame, longer_magnitude
from appliance.vision.detection import (
    BIRTH_FRACTION,
    BIRTH_LIKELIHOOD,
    BIRTH_SPREAD_PX,
    ImportanceDensity,
    birth_positions,
    resample_particles,
)
from appliance.vision.epipolar import translation_from_theta
from appliance.vision.flow import FB_LENGTH_GAIN, Tracks, corner_candidates, fb_covariance, track
from appliance.vision.geometry import (
    FloatArray,
    PinholeCamera,
    epipole,
    euler_to_matrix,
    lk_start,
    matrix_to_euler,
    vehicle_from_camera_rotation,
)
from appliance.vision.likelihood import (
    CameraMotion,
    Cues,
    RoadPlane,
    combine,
    foot_points,
    motion_cues,
)
from appliance.vision.msac import weighted_minimal_samples
from appliance.vision.prior import PriorMotion, prior_motion
from appliance.vision.refinement import MapProblem, refine_motion

ATTITUDE_LEAK = 0.9      # per frame: the body pitch/roll estimate decays towards the mount's
FOOT_PROBABILITY = 0.3   # a run of the previous p(x) at least this is an object a pixel stands on
FOOT_GAP_PX = 8.0        # px, that run starts at most this far below the pixel


class FrameFormatError(UsageError):
    """A frame that does not fit the camera model (size or pixel type); the frame is not used."""


@dataclass(frozen=True)
class VisionState:
    """What the vision core carries from one frame to the next.

    prev_image: (H, W) uint8 gray of the previous frame (None before the first);
    prev_t: its capture time (s); prev_sensors: CAN/PTU sample at that time;
    particles: (N, 2) px, where flow is measured from the previous frame;
    attitude: (3, 3) estimated rotation from the nominal camera (mount + PTU on a
    level vehicle) to the actual one (body pitch/roll), used for the road plane;
    seed, frames: the random generator of frame k is ``default_rng([seed, k])``;
    past: the frames before the previous one, oldest first, for the longer baseline
    (:mod:`~appliance.vision.baseline`).
    """

    seed: int
    frames: int
    prev_image: NDArray[np.uint8] | None
    prev_t: float
    prev_sensors: SensorSample | None
    particles: FloatArray
    attitude: FloatArray
    past: tuple[PastFrame, ...] = ()


def _rng(seed: int, k: int) -> np.random.Generator:
    return np.random.default_rng([seed, k])


def init_vision_state(cfg: Config, camera: PinholeCamera, seed: int) -> VisionState:
    """State before the first frame: particles spread by the importance function g."""
    particles = ImportanceDensity(camera.width, camera.height).sample(_rng(seed, 0),
                                                                       cfg.detection.particles)
    return VisionState(seed=seed, frames=0, prev_image=None, prev_t=math.nan, prev_sensors=None,
                       particles=particles, attitude=np.eye(3))


def check_frame(frame: Frame, camera: PinholeCamera) -> None:
    """Raise :class:`FrameFormatError` unless the frame is 8-bit gray of the camera's size.

    The sources deliver gray frames of the configured size (the camera driver converts,
    the recording reader checks against ``meta.toml``); anything else is refused here,
    before the pipeline touches its state, rather than guessed around.
    """
    img = frame.image
    if img.dtype != np.uint8:
        raise FrameFormatError(f"frame {frame.index}: pixels are {img.dtype}, expected 8-bit (uint8)")
    if img.shape != (camera.height, camera.width):
        dims = img.shape[1::-1] + img.shape[2:] if img.ndim >= 2 else img.shape
        size = "x".join(str(d) for d in dims)
        raise FrameFormatError(f"frame {frame.index}: image is {size}, the camera is configured "
                               f"for {camera.width}x{camera.height} gray")


def _road(cfg: Config, sensors: SensorSample | None, attitude: FloatArray) -> RoadPlane:
    pan = sensors.pan_rad if sensors is not None and math.isfinite(sensors.pan_rad) else 0.0
    tilt = sensors.tilt_rad if sensors is not None and math.isfinite(sensors.tilt_rad) else 0.0
    R_vc = vehicle_from_camera_rotation(cfg.mount.pitch_rad, pan, tilt) @ attitude
    return RoadPlane(normal=R_vc.T @ np.array([0.0, 0.0, 1.0]), height_m=cfg.mount.z_m)


def _unit(v: FloatArray) -> FloatArray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0.0 else np.zeros(3)


def _epipole(camera: PinholeCamera, t: FloatArray) -> tuple[float, float] | None:
    if not np.any(t):
        return None
    e = epipole(camera, t)
    return None if e is None else (float(e[0]), float(e[1]))


def _first_frame(state: VisionState, image: NDArray[np.uint8], frame: Frame,
                 sensors: SensorSample, cfg: Config) -> tuple[VisionState, EgoMotion, ParticleSet]:
    zero = np.zeros(3)
    standstill = not (math.isfinite(sensors.speed_m_s)
                      and abs(sensors.speed_m_s) >= cfg.detection.standstill_speed_m_s)
    ego = EgoMotion(rotation=zero, translation_dir=zero, epipole_px=None, prior_rotation=zero,
                    prior_translation_dir=zero, prior_epipole_px=None, inliers=0, confident=False,
                    standstill=standstill)
    n = len(state.particles)
    particles = ParticleSet(positions=state.particles.copy(), flow=np.zeros((n, 2)),
                            weights=np.zeros(n), valid=np.zeros(n, dtype=bool),
                            window_px=cfg.flow.window_px, flow_std_px=cfg.detection.sigma_p_px)
    new = dataclasses.replace(state, frames=state.frames + 1, prev_image=image, prev_t=frame.t,
                              prev_sensors=sensors)
    return new, ego, particles


def static_pool(image: NDArray[np.uint8], prob_map: ProbabilityMap | None, cfg: Config,
                 rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
    """Static-scene correspondences' start points (S, 2) and their ``1 - p(x)`` (S,)."""
    n = cfg.refinement.static_points
    h, w = image.shape
    cell = max(8, int(math.sqrt(h * w / (2.0 * n))))
    pos, _ = corner_candidates(image, cell)
    p = prob_map.at(pos).astype(np.float64) if prob_map is not None else np.zeros(len(pos))
    keep = 1.0 - np.clip(p, 0.0, 1.0)
    if len(pos) > n:   # fig. 6 step 1: drawn with probability 1 - p(x)
        idx = weighted_minimal_samples(rng, keep, 1, n)[0]
        pos, keep = pos[idx], keep[idx]
    return pos, keep


def _refine(prior: PriorMotion, xp: FloatArray, xc: FloatArray, keep: FloatArray, cfg: Config,
            camera: PinholeCamera, rng: np.random.Generator) -> tuple[FloatArray, int, bool]:
    """Refined theta (5,) (polar angles kept from the prior at a standstill), inliers, confident."""
    translating = not prior.standstill
    sl = slice(0, 5) if translating else slice(2, 5)
    problem = MapProblem(theta_bar=prior.theta[sl], sigma=prior.sigma[sl], K=camera.K,
                         sigma_l_px=cfg.refinement.sigma_l_px, translating=translating)
    result = refine_motion(problem, xp, xc, keep, cfg.refinement, rng)
    theta = prior.theta.copy()
    theta[sl] = result.theta
    return theta, int(result.inliers.sum()), result.confident


def _longer_baseline(cues: Cues, past: tuple[PastFrame, ...], image: NDArray[np.uint8], t: float,
                     tracks: Tracks, ideal_start: FloatArray, ideal_end: FloatArray,
                     road: RoadPlane, motion: CameraMotion, cfg: Config, camera: PinholeCamera
                     ) -> Cues:
    """``cues`` with the flow-length cue of the valid tracks (ideal pixels ``ideal_start`` of
    the previous frame to ``ideal_end``, (M, 2) each) whose road flow is short measured over the
    longer baseline instead (:func:`baseline.longer_magnitude`)."""
    if cues.magnitude is None:
        return cues
    ok = np.flatnonzero(tracks.valid)
    longer, measured = longer_magnitude(past, image, t, tracks.end[ok], ideal_end[ok],
                                        ideal_start[ok], road, motion, cfg, camera)
    magnitude = cues.magnitude.copy()
    magnitude[ok[measured]] = longer[measured]
    return Cues(cues.direction, magnitude, None)


def perceive(state: VisionState, frame: Frame, sensors: SensorSample,
             prob_map: ProbabilityMap | None, cfg: Config, camera: PinholeCamera
             ) -> tuple[VisionState, EgoMotion, ParticleSet]:
    """One frame of the vision core; see the module docstring.

    ``frame`` is 8-bit gray of the camera's size (:func:`check_frame`, which
    ``pipeline.step`` applies first). Missing CAN, too few correspondences and a
    covered camera do not raise: they give the prior, ``confident`` False, and no
    detections.
    """
    image = np.ascontiguousarray(frame.image)
    if state.prev_image is None or state.prev_sensors is None:
        return _first_frame(state, image, frame, sensors, cfg)
    rng = _rng(state.seed, state.frames)
    prev_s = dataclasses.replace(state.prev_sensors, t=state.prev_t)
    cur_s = dataclasses.replace(sensors, t=frame.t)
    prior = prior_motion(cfg.mount, cfg.refinement, prev_s, cur_s,
                         cfg.detection.standstill_speed_m_s)

    # optical flow: both pools in one forward call, both checked backwards
    static_start, keep = static_pool(state.prev_image, prob_map, cfg, rng)
    n = len(state.particles)
    start = np.vstack([state.particles, static_start])
    # LK starts where the prior rotation alone moves each point (a PTU pan of 15 px per frame
    # stays within the pyramid's reach)
    guess = lk_start(camera, start, prior.R)
    tracks = track(state.prev_image, image, start, np.ones(len(start), dtype=bool), cfg.flow,
                   guess=guess)
    ideal_start = camera.undistort(start)
    ideal_end = camera.undistort(tracks.end)

    # refinement (section 3)
    ok = tracks.valid[n:]
    theta, inliers, refined = _refine(prior, ideal_start[n:][ok], ideal_end[n:][ok], keep[ok], cfg,
                                      camera, rng)
    R = euler_to_matrix(theta[2:])
    t_dir = np.zeros(3) if prior.standstill else translation_from_theta(theta[None, :])[0]
    length = float(np.linalg.norm(prior.t_m))
    t_m = t_dir * length if prior.metric and not prior.standstill else None
    attitude = prior.R @ state.attitude @ R.T
    attitude = euler_to_matrix(ATTITUDE_LEAK * matrix_to_euler(attitude))
    road = _road(cfg, sensors, attitude)

    # detection (section 2): the likelihood at both pools; the particles' weighs them,
    # the static pool's seeds births
    valid = tracks.valid[:n]
    motion = CameraMotion(R=R, t_dir=t_dir, t_m=t_m, standstill=prior.standstill, K=camera.K)
    cov = fb_covariance(tracks.fb_error)
    length_cov = fb_covariance(tracks.fb_error, FB_LENGTH_GAIN)
    foot = None
    if prob_map is not None:
        feet = foot_points(prob_map.p, prob_map.scale, tracks.end, FOOT_PROBABILITY,
                           camera.height, FOOT_GAP_PX)
        foot = camera.undistort(np.nan_to_num(feet, nan=0.0))
        foot[np.isnan(feet[:, 0])] = np.nan
    cues = motion_cues(ideal_start, ideal_end, motion, road, cfg.detection, cov, foot, length_cov)
    past = (*state.past, PastFrame(state.prev_image, state.prev_t,
                                   None if t_m is None else (R, t_m)))[-HISTORY:]
    cues = _longer_baseline(cues, past, image, frame.t, tracks, ideal_start, ideal_end, road,
                            motion, cfg, camera)
    lik_all = np.where(tracks.valid, np.clip(combine(cues, cfg.detection.likelihood), 0.0, 1.0), 0.0)
    weights = lik_all[:n]
    end = tracks.end[:n]
    births = birth_positions(tracks.end[n:], lik_all[n:], round(BIRTH_FRACTION * n),
                             BIRTH_LIKELIHOOD, BIRTH_SPREAD_PX, camera.width, camera.height, rng)
    particles = resample_particles(end, weights, valid, ImportanceDensity(camera.width, camera.height),
                                   cfg.detection, rng, births)

    prior_dir = _unit(prior.t_m)
    ego = EgoMotion(rotation=theta[2:].copy(), translation_dir=t_dir, epipole_px=_epipole(camera, t_dir),
                    prior_rotation=prior.theta[2:].copy(), prior_translation_dir=prior_dir,
                    prior_epipole_px=_epipole(camera, prior_dir), inliers=inliers,
                    confident=refined and not prior.wide, standstill=prior.standstill)
    out = ParticleSet(positions=end.copy(), flow=end - state.particles, weights=weights,
                      valid=valid.copy(), window_px=cfg.flow.window_px,
                      flow_std_px=cfg.detection.sigma_p_px)
    new = VisionState(seed=state.seed, frames=state.frames + 1, prev_image=image, prev_t=frame.t,
                      prev_sensors=sensors, particles=particles, attitude=attitude, past=past)
    return new, ego, out
