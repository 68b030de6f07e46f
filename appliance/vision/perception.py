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

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.errors import UsageError
from appliance.messages import EgoMotion, Frame, ParticleSet, ProbabilityMap, SensorSample
from appliance.vision.baseline import advance_history, inherit_history, lineage_weight
from appliance.vision.boundary import flow_spread, isolated_likelihood, neighbour_points
from appliance.vision.detection import (
    ImportanceDensity,
    birth_positions,
    resample_particles,
    road_importance,
)
from appliance.vision.epipolar import translation_from_theta
from appliance.vision.flow import corner_candidates, lk_covariance, track
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
    RoadPlane,
    combine,
    foot_points,
    horizon_row,
    motion_cues,
)
from appliance.vision.msac import weighted_minimal_samples
from appliance.vision.prior import PriorMotion, prior_motion
from appliance.vision.refinement import MapProblem, refine_motion
from appliance.vision.span import span_motion

LOOKS_INDEPENDENT = 0.5   # a likelihood at least this looks independent (occlusion-edge tests, boundary.py)
ATTITUDE_LEAK = 0.9   # per frame: the body pitch/roll estimate decays towards the mount's


class FrameFormatError(UsageError):
    """A frame that does not fit the camera model (size or pixel type); the frame is not used."""


@dataclass(frozen=True)
class VisionState:
    """What the vision core carries from one frame to the next.

    prev_image: (H, W) uint8 gray of the previous frame (None before the first);
    prev_t: its capture time (s); prev_sensors: CAN/PTU sample at that time;
    particles: (N, 2) px, where flow is measured from the previous frame;
    correction: (N,) eq. 4 factor of each particle (1 unless drawn from g);
    attitude: (3, 3) estimated rotation from the nominal camera (mount + PTU on a
    level vehicle) to the actual one (body pitch/roll), used for the road plane;
    seed, frames: the random generator of frame k is ``default_rng([seed, k])``;
    history: (N, k-1) likelihoods of each particle's lineage in the k-1 frames before
    (newest first, NaN: unknown; ``baseline``, k = ``detection.baseline_frames``);
    earlier_images: the m-1 gray frames before ``prev_image`` and earlier_motions: the
    camera motions into ``prev_image`` and into each of those but the oldest (newest
    first, m = ``detection.span_frames``; ``span``).
    """

    seed: int
    frames: int
    prev_image: NDArray[np.uint8] | None
    prev_t: float
    prev_sensors: SensorSample | None
    particles: FloatArray
    correction: FloatArray
    attitude: FloatArray
    history: FloatArray
    earlier_images: tuple[NDArray[np.uint8], ...] = ()
    earlier_motions: tuple[CameraMotion, ...] = ()


def _rng(seed: int, k: int) -> np.random.Generator:
    return np.random.default_rng([seed, k])


def init_vision_state(cfg: Config, camera: PinholeCamera, seed: int) -> VisionState:
    """State before the first frame: particles spread by the importance function g."""
    g = _importance(cfg, camera, None)
    particles = g.sample(_rng(seed, 0), cfg.detection.particles)
    return VisionState(seed=seed, frames=0, prev_image=None, prev_t=math.nan, prev_sensors=None,
                       particles=particles, correction=g.correction(particles), attitude=np.eye(3),
                       history=_no_history(len(particles), cfg))


def _no_history(n: int, cfg: Config) -> FloatArray:
    return np.full((n, cfg.detection.baseline_frames - 1), np.nan)


def _gray(frame: Frame, camera: PinholeCamera) -> NDArray[np.uint8]:
    img = np.asarray(frame.image)
    if img.dtype != np.uint8:
        raise FrameFormatError(f"frame {frame.index}: pixels are {img.dtype}, expected 8-bit (uint8)")
    if img.ndim == 3 and img.shape[2] == 3:
        img = np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim != 2 or img.shape != (camera.height, camera.width):
        size = "x".join(str(s) for s in img.shape[1::-1]) if img.ndim >= 2 else str(img.shape)
        raise FrameFormatError(f"frame {frame.index}: image is {size}, the camera is configured "
                               f"for {camera.width}x{camera.height}")
    return np.ascontiguousarray(img)


def _road(cfg: Config, sensors: SensorSample | None, attitude: FloatArray) -> RoadPlane:
    pan = sensors.pan_rad if sensors is not None and math.isfinite(sensors.pan_rad) else 0.0
    tilt = sensors.tilt_rad if sensors is not None and math.isfinite(sensors.tilt_rad) else 0.0
    R_vc = vehicle_from_camera_rotation(cfg.mount.pitch_rad, pan, tilt) @ attitude
    return RoadPlane(normal=R_vc.T @ np.array([0.0, 0.0, 1.0]), height_m=cfg.mount.z_m)


def _importance(cfg: Config, camera: PinholeCamera, road: RoadPlane | None) -> ImportanceDensity:
    if cfg.detection.importance == "road":
        road = road or _road(cfg, None, np.eye(3))
        return road_importance(camera.width, camera.height, horizon_row(road, camera.K))
    return ImportanceDensity(camera.width, camera.height)


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


def perceive(state: VisionState, frame: Frame, sensors: SensorSample,
             prob_map: ProbabilityMap | None, cfg: Config, camera: PinholeCamera
             ) -> tuple[VisionState, EgoMotion, ParticleSet]:
    """One frame of the vision core; see the module docstring.

    Raises :class:`FrameFormatError` (before touching anything) for a frame whose
    size or pixel type does not match ``camera``; the caller drops that frame and
    the next good one continues from ``state``. Missing CAN, too few
    correspondences and a covered camera do not raise: they give the prior,
    ``confident`` False, and no detections.
    """
    image = _gray(frame, camera)
    if state.prev_image is None or state.prev_sensors is None:
        return _first_frame(state, image, frame, sensors, cfg)
    rng = _rng(state.seed, state.frames)
    prev_s = dataclasses.replace(state.prev_sensors, t=state.prev_t)
    cur_s = dataclasses.replace(sensors, t=frame.t)
    prior = prior_motion(cfg.mount, cfg.refinement, prev_s, cur_s,
                         cfg.detection.standstill_speed_m_s)

    # optical flow: both pools in one forward call, backward check of the static pool
    static_start, keep = static_pool(state.prev_image, prob_map, cfg, rng)
    n = len(state.particles)
    start = np.vstack([state.particles, static_start])
    check = np.zeros(len(start), dtype=bool)
    check[n:] = True
    check[:n] = cfg.flow.fb_check_particles
    # LK starts where the prior rotation alone moves each point
    guess = lk_start(camera, start, prior.R) if cfg.flow.rotation_guess else None
    tracks = track(state.prev_image, image, start, check, cfg.flow, guess=guess)
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

    # detection (section 2)
    valid = tracks.valid[:n]
    motion = CameraMotion(R=R, t_dir=t_dir, t_m=t_m, standstill=prior.standstill, K=camera.K)
    # the likelihood at both pools: the particles' weighs them, the static pool's seeds births
    cov_all = lk_covariance(state.prev_image, start, tracks.residual, cfg.flow.window_px,
                            cfg.detection.lk_noise_gain, cfg.detection.image_noise_gray,
                            tracks.fb_error, cfg.detection.fb_noise_gain)
    foot_all = None
    if prob_map is not None and cfg.detection.foot_probability > 0.0:
        feet = foot_points(prob_map.p, prob_map.scale, tracks.end,
                           cfg.detection.foot_probability, camera.height,
                           cfg.detection.foot_gap_px)
        foot_all = camera.undistort(np.nan_to_num(feet, nan=0.0))
        foot_all[np.isnan(feet[:, 0])] = np.nan
    cues = motion_cues(ideal_start, ideal_end, motion, road, cfg.detection, cov_all, foot_all)
    lik_all = np.where(tracks.valid, np.clip(combine(cues, cfg.detection.likelihood), 0.0, 1.0), 0.0)
    if cfg.detection.isolation_spacing_px > 0.0 and not prior.standstill:
        lik_all = _isolation_check(state.prev_image, image, start, lik_all, tracks.valid, prior.R,
                                   motion, road, cfg, camera)
    if cfg.detection.stability_offset_px > 0.0 and not prior.standstill:
        lik_all = _stability_check(state.prev_image, image, start, tracks.end, ideal_start,
                                   ideal_end, lik_all, tracks.valid, cov_all, foot_all, motion,
                                   road, cfg)
    likelihood = lik_all[:n]
    cov = None if cov_all is None else cov_all[:n]
    foot = None if foot_all is None else foot_all[:n]
    end = tracks.end[:n]
    likelihood = _span_likelihood(state, image, end, valid, cov, likelihood, motion, road, foot,
                                  cfg, camera)
    history = _no_history(n, cfg) if prior.standstill else state.history
    weights = lineage_weight(likelihood, history)
    g = _importance(cfg, camera, road)
    births = birth_positions(tracks.end[n:], lik_all[n:], round(cfg.detection.birth_fraction * n),
                             cfg.detection.birth_likelihood, cfg.detection.birth_spread_px,
                             camera.width, camera.height, rng)
    particles, correction, parent, _ = resample_particles(end, weights, valid, state.correction,
                                                          g, cfg.detection, rng, births)
    history = inherit_history(advance_history(history, likelihood, valid), parent)

    prior_dir = _unit(prior.t_m)
    ego = EgoMotion(rotation=theta[2:].copy(), translation_dir=t_dir, epipole_px=_epipole(camera, t_dir),
                    prior_rotation=prior.theta[2:].copy(), prior_translation_dir=prior_dir,
                    prior_epipole_px=_epipole(camera, prior_dir), inliers=inliers,
                    confident=refined and not prior.wide, standstill=prior.standstill)
    out = ParticleSet(positions=end.copy(), flow=end - state.particles, weights=weights,
                      valid=valid.copy(), window_px=cfg.flow.window_px,
                      flow_std_px=cfg.detection.sigma_p_px)
    kept = cfg.detection.span_frames - 1   # frames the next span reaches back beyond prev_image
    new = VisionState(seed=state.seed, frames=state.frames + 1, prev_image=image, prev_t=frame.t,
                      prev_sensors=sensors, particles=particles, correction=correction,
                      attitude=attitude, history=history,
                      earlier_images=((state.prev_image,) + state.earlier_images)[:kept],
                      earlier_motions=((motion,) + state.earlier_motions)[:kept])
    return new, ego, out


def _isolation_check(prev: NDArray[np.uint8], image: NDArray[np.uint8], start: FloatArray,
                     likelihood: FloatArray, valid: NDArray[np.bool_], prior_R: FloatArray,
                     motion: CameraMotion, road: RoadPlane, cfg: Config, camera: PinholeCamera
                     ) -> FloatArray:
    """The likelihood with isolated evidence capped (boundary.py): flow measured
    ``isolation_spacing_px`` to either side of every point that looks independent."""
    det = cfg.detection
    cand = np.flatnonzero(valid & (likelihood >= LOOKS_INDEPENDENT))
    if cand.size == 0:
        return likelihood
    pts = neighbour_points(start[cand], det.isolation_spacing_px).reshape(-1, 2)
    guess = lk_start(camera, pts, prior_R) if cfg.flow.rotation_guess else None
    nb = track(prev, image, pts, np.ones(len(pts), dtype=bool), cfg.flow, guess=guess)
    cues = motion_cues(camera.undistort(pts), camera.undistort(nb.end), motion, road, det)
    nb_lik = np.clip(combine(cues, det.likelihood), 0.0, 1.0)
    out = likelihood.copy()
    out[cand] = isolated_likelihood(likelihood[cand], nb_lik.reshape(-1, 4),
                                    nb.valid.reshape(-1, 4), LOOKS_INDEPENDENT,
                                    det.isolation_min_valid)
    return out


def _stability_check(prev: NDArray[np.uint8], image: NDArray[np.uint8], start: FloatArray,
                     end: FloatArray, ideal_start: FloatArray, ideal_end: FloatArray,
                     likelihood: FloatArray, valid: NDArray[np.bool_], cov: FloatArray | None,
                     foot: FloatArray | None, motion: CameraMotion, road: RoadPlane,
                     cfg: Config) -> FloatArray:
    """The likelihood of every point that looks independent again, its flow's std widened by
    how much its flow changes when the window moves by ``stability_offset_px`` (boundary.py)."""
    det = cfg.detection
    cand = np.flatnonzero(valid & (likelihood >= LOOKS_INDEPENDENT))
    if cand.size == 0:
        return likelihood
    # each neighbour starts at its particle's answer, so one pyramid level and no backward
    # check suffice: what is measured is how far the answer moves, not whether it is found
    flow = end[cand] - start[cand]
    pts = neighbour_points(start[cand], det.stability_offset_px).reshape(-1, 2)
    guess = pts + np.repeat(flow, 4, axis=0)
    nb = track(prev, image, pts, np.zeros(len(pts), dtype=bool),
               dataclasses.replace(cfg.flow, pyramid_levels=0), guess=guess)
    spread = flow_spread(flow, (nb.end - pts).reshape(-1, 4, 2), nb.valid.reshape(-1, 4))
    var = (det.stability_gain * np.maximum(spread - det.stability_floor_px, 0.0)) ** 2
    extra = np.column_stack([var, np.zeros_like(var), var])
    cov_c = extra if cov is None else cov[cand] + extra
    cues = motion_cues(ideal_start[cand], ideal_end[cand], motion, road, det, cov_c,
                       None if foot is None else foot[cand])
    out = likelihood.copy()
    out[cand] = np.clip(combine(cues, det.likelihood), 0.0, 1.0)
    return out


def _span_likelihood(state: VisionState, image: NDArray[np.uint8], end: FloatArray,
                     valid: NDArray[np.bool_], cov: FloatArray | None, likelihood: FloatArray,
                     motion: CameraMotion, road: RoadPlane, foot: FloatArray | None, cfg: Config,
                     camera: PinholeCamera) -> FloatArray:
    """Each particle's likelihood from its flow over the last m frames (``span``): its start
    traced back m - 1 frames, weighed with the motion composed over the span; the
    one-frame ``likelihood`` where the trace fails, and for all while fewer than m frames
    are known or a standstill falls in the span."""
    m = min(cfg.detection.span_frames, len(state.earlier_images) + 1)   # the motions are kept alike
    if m < 2 or state.prev_image is None:
        return likelihood
    span = span_motion(motion, state.earlier_motions, m)
    if span.standstill:
        return likelihood
    idx = np.flatnonzero(valid)
    start, stop = state.particles[idx], end[idx]
    back = track(state.prev_image, state.earlier_images[m - 2], start, np.ones(len(idx), dtype=bool),
                 cfg.flow, guess=start - (m - 1) * (stop - start))
    det = cfg.detection
    cov_back = lk_covariance(state.prev_image, start, back.residual, cfg.flow.window_px,
                             det.lk_noise_gain, det.image_noise_gray, back.fb_error, det.fb_noise_gain)
    # the span's flow is the trace back plus this frame's flow: their errors add
    total = cov_back if cov is None else (cov[idx] if cov_back is None else cov[idx] + cov_back)
    cues = motion_cues(camera.undistort(back.end), camera.undistort(stop), span, road, det, total,
                       None if foot is None else foot[idx])
    out = likelihood.copy()
    out[idx] = np.where(back.valid, np.clip(combine(cues, det.likelihood), 0.0, 1.0), likelihood[idx])
    return out
