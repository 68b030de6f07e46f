"""Section 3: epipolar distances, batched LM, preemptive MSAC and the CAN/PTU prior."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares

from appliance.config import Config
from appliance.messages import SensorSample
from appliance.vision import geometry as g
from appliance.vision.epipolar import (
    epipolar_distances,
    essential_matrices,
    heading_from_polar,
    polar_from_translation,
    rays,
    transfer_residuals,
    translation_from_theta,
)
from appliance.vision.likelihood import derotate
from appliance.vision.lm import batched_lm
from appliance.vision.msac import truncated_loss, weighted_minimal_samples
from appliance.vision.prior import WIDE_PRIOR_FACTOR, prior_motion, vehicle_arc
from appliance.vision.refinement import (
    MIN_CORRESPONDENCES,
    MapProblem,
    map_residuals,
    refine_motion,
)

CAM = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
K = CAM.K


def scene_points(rng: np.random.Generator, m: int) -> np.ndarray:
    """m static points (m, 3) in the previous camera frame, 4-60 m deep, all over the image."""
    z = rng.uniform(4.0, 60.0, m)
    u, v = rng.uniform(0, 640, m), rng.uniform(0, 480, m)
    return np.column_stack([(u - CAM.cx) / CAM.fx * z, (v - CAM.cy) / CAM.fy * z, z])


def correspondences(r: np.ndarray, t: np.ndarray, m: int = 300, seed: int = 0
                    ) -> tuple[np.ndarray, np.ndarray]:
    X = scene_points(np.random.default_rng(seed), m)
    x_prev = CAM.project(X)
    x_cur = CAM.project(X @ g.euler_to_matrix(r).T + t)
    return x_prev, x_cur


def truth_theta(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.concatenate([polar_from_translation(t), r])


R_TRUE = np.array([0.004, -0.003, 0.001])     # rad: a bump's pitch, some yaw, a little roll
T_TRUE = np.array([0.02, 0.01, -0.4])         # m: forward 0.4 m, a little sideways and down


def test_polar_parameterisation_round_trips_and_forward_is_zero() -> None:
    np.testing.assert_allclose(polar_from_translation(np.array([0.0, 0.0, -2.0])), [0.0, 0.0])
    t = np.array([0.3, -0.2, -0.9])
    phi, psi = polar_from_translation(t)
    np.testing.assert_allclose(-heading_from_polar(phi, psi), t / np.linalg.norm(t), atol=1e-12)


def test_pure_rotation_gives_zero_translational_residual() -> None:
    X = scene_points(np.random.default_rng(3), 50)
    for depth_scale in (0.1, 1.0, 10.0):
        x_prev = CAM.project(X * depth_scale)
        x_cur = CAM.project((X * depth_scale) @ g.euler_to_matrix(R_TRUE).T)
        residual = x_cur - derotate(K, g.euler_to_matrix(R_TRUE), x_prev)
        assert np.max(np.abs(residual)) < 1e-9
        assert np.max(np.abs(transfer_residuals(R_TRUE[None], x_prev, x_cur, K))) < 1e-9
        # and every epipolar line passes through its point, whatever the translation direction
        theta = np.concatenate([[0.3, -0.1], R_TRUE])[None, :]
        assert np.max(np.abs(epipolar_distances(theta, x_prev, x_cur, K))) < 1e-9


def test_epipolar_distance_is_zero_for_the_true_motion_and_measures_pixels() -> None:
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE)
    theta = truth_theta(R_TRUE, T_TRUE)[None, :]
    assert np.max(np.abs(epipolar_distances(theta, x_prev, x_cur, K))) < 1e-9
    # moving a point 2 px perpendicular to its epipolar line gives |d| = 2
    e = g.epipole(CAM, translation_from_theta(theta)[0])
    assert e is not None
    p = derotate(K, g.euler_to_matrix(R_TRUE), x_prev[:1])[0]
    direction = (p - e) / np.linalg.norm(p - e)
    normal = np.array([-direction[1], direction[0]])
    d = epipolar_distances(theta, x_prev[:1], x_cur[:1] + 2.0 * normal, K)
    assert abs(abs(d[0, 0]) - 2.0) < 1e-3


def test_essential_matrices_are_the_cross_product_of_t_with_the_rotation() -> None:
    # written out entry by entry for speed: each must be [t]_x R of the state's own R and t
    theta = np.random.default_rng(5).uniform(-1.0, 1.0, (7, 5))
    E = essential_matrices(theta)
    for th, e in zip(theta, E):
        R = g.euler_to_matrix(th[2:])
        t = translation_from_theta(th[None, :])[0]
        # [t]_x R, column by column
        np.testing.assert_allclose(e, np.cross(t[None, :], R.T).T, atol=1e-12)
    # and b . E a = 0 for the rays of the true motion's static points
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE)
    a, b = rays(x_prev, K), rays(x_cur, K)
    E_true = essential_matrices(truth_theta(R_TRUE, T_TRUE)[None, :])[0]
    assert np.max(np.abs(np.einsum("mi,ij,mj->m", b, E_true, a))) < 1e-12


def wide_problem(theta_bar: np.ndarray) -> MapProblem:
    return MapProblem(theta_bar=theta_bar, sigma=np.full(5, 100.0), K=K, sigma_l_px=0.5,
                      translating=True)


def test_noise_free_correspondences_recover_the_motion_to_1e_6(default_config: Config) -> None:
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE)
    truth = truth_theta(R_TRUE, T_TRUE)
    start = truth + np.array([0.03, -0.02, 0.01, 0.01, -0.01])   # a prior 0.6-1.7 deg off
    result = refine_motion(wide_problem(start), x_prev, x_cur, np.ones(len(x_prev)),
                           default_config.refinement, np.random.default_rng(0))
    assert result.confident
    np.testing.assert_allclose(result.theta, truth, atol=1e-6)
    assert result.inliers.all()


def rotation_error_deg(theta: np.ndarray, r_true: np.ndarray) -> float:
    R = g.euler_to_matrix(theta[2:5])
    return math.degrees(float(g.rotation_angle(R.T @ g.euler_to_matrix(r_true))))


def heading_error_deg(theta: np.ndarray, t_true: np.ndarray) -> float:
    t = translation_from_theta(theta[None, :])[0]
    c = float(np.dot(t, t_true / np.linalg.norm(t_true)))
    return math.degrees(math.acos(min(1.0, c)))


def outlier_case(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, MapProblem]:
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE, seed=seed)
    rng = np.random.default_rng(seed + 100)
    bad = rng.random(len(x_prev)) < 0.3
    x_cur = x_cur.copy()
    x_cur[bad] += rng.uniform(-15.0, 15.0, (int(bad.sum()), 2))
    prior = truth_theta(R_TRUE, T_TRUE) + np.array([0.02, -0.02, 0.004, -0.002, 0.002])
    problem = MapProblem(theta_bar=prior, sigma=np.array([0.02, 0.02, 0.004, 0.002, 0.002]), K=K,
                         sigma_l_px=0.5, translating=True)
    return x_prev, x_cur, bad, problem


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_msac_recovers_the_motion_within_0_05_deg_with_30_percent_outliers(
        default_config: Config, seed: int) -> None:
    x_prev, x_cur, bad, problem = outlier_case(seed)
    result = refine_motion(problem, x_prev, x_cur, np.ones(len(x_prev)), default_config.refinement,
                           np.random.default_rng(seed))
    assert result.confident
    assert rotation_error_deg(result.theta, R_TRUE) < 0.05
    # the heading is weakly observable from 0.4 m of travel (a 1 deg change moves most
    # epipolar lines by 0.1-0.2 px), so the prior (1.2 deg off here) and the few outliers
    # that land within 1 px of their line pull it more: the epipole target is 1 deg
    assert heading_error_deg(result.theta, T_TRUE) < 1.0
    # nearly all outliers rejected, all inliers kept
    assert result.inliers[~bad].all()
    assert result.inliers[bad].mean() < 0.15


def test_without_msac_the_outliers_spoil_the_map_estimate(default_config: Config) -> None:
    x_prev, x_cur, _, problem = outlier_case(0)
    theta, _ = batched_lm(map_residuals(problem, x_prev, x_cur), problem.theta_bar[None, :], 20)
    assert rotation_error_deg(theta[0], R_TRUE) > 0.05


def test_batched_lm_finds_the_same_minimum_as_scipy_least_squares() -> None:
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE, m=80, seed=5)
    x_cur = x_cur + np.random.default_rng(6).normal(0.0, 0.3, x_cur.shape)
    prior = truth_theta(R_TRUE, T_TRUE) + np.array([0.01, 0.01, 0.003, -0.002, 0.001])
    problem = MapProblem(theta_bar=prior, sigma=np.array([0.02, 0.02, 0.004, 0.002, 0.002]), K=K,
                         sigma_l_px=0.5, translating=True)
    residuals = map_residuals(problem, x_prev, x_cur)
    ours, _ = batched_lm(residuals, prior[None, :], 30)
    ref = least_squares(lambda th: residuals(th[None, None, :])[0, 0], prior, method="lm",
                        xtol=1e-14, ftol=1e-14)
    np.testing.assert_allclose(ours[0], ref.x, atol=1e-7)


def test_batched_lm_solves_problems_with_different_data_in_one_batch() -> None:
    cases = [correspondences(R_TRUE * s, T_TRUE, m=12, seed=s) for s in (1, 2, 3)]
    x_prev = np.stack([c[0] for c in cases])
    x_cur = np.stack([c[1] for c in cases])
    start = truth_theta(R_TRUE, T_TRUE)
    theta, cost = batched_lm(map_residuals(wide_problem(start), x_prev, x_cur),
                             np.repeat(start[None, :], 3, axis=0), 20)
    for s, th in zip((1, 2, 3), theta):
        assert rotation_error_deg(th, R_TRUE * s) < 1e-4
    assert np.all(cost < 1e-6)


def test_standstill_refines_the_rotation_from_transfer_errors(default_config: Config) -> None:
    X = scene_points(np.random.default_rng(9), 200)
    r = np.array([0.0, 0.02, 0.0])   # the PTU panned by about 1.1 degrees
    x_prev, x_cur = CAM.project(X), CAM.project(X @ g.euler_to_matrix(r).T)
    problem = MapProblem(theta_bar=np.zeros(3), sigma=np.full(3, 0.05), K=K, sigma_l_px=0.5,
                         translating=False)
    result = refine_motion(problem, x_prev, x_cur, np.ones(200), default_config.refinement,
                           np.random.default_rng(0))
    assert result.confident
    np.testing.assert_allclose(result.theta, r, atol=1e-6)


def test_too_few_correspondences_keep_the_prior(default_config: Config) -> None:
    x_prev, x_cur = correspondences(R_TRUE, T_TRUE, m=MIN_CORRESPONDENCES - 1)
    prior = truth_theta(R_TRUE, T_TRUE) + 0.01
    result = refine_motion(wide_problem(prior), x_prev, x_cur, np.ones(len(x_prev)),
                           default_config.refinement, np.random.default_rng(0))
    assert not result.confident
    np.testing.assert_array_equal(result.theta, prior)


def test_minimal_samples_are_distinct_and_avoid_likely_movers() -> None:
    rng = np.random.default_rng(0)
    w = np.ones(100)
    w[:50] = 0.02                      # p(x) = 0.98 on the first half
    idx = weighted_minimal_samples(rng, w, 400, 5)
    assert idx.shape == (400, 5)
    assert all(len(set(row)) == 5 for row in idx.tolist())
    share = np.mean(idx < 50)
    assert share < 0.05                # ~2 % expected, 50 % if the weights were ignored
    with pytest.raises(ValueError):
        weighted_minimal_samples(rng, np.ones(3), 1, 5)


def test_truncated_loss_caps_each_error_at_t_squared() -> None:
    delta = np.array([[0.5, 3.0, np.nan], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(truncated_loss(delta, 1.0), [0.25 + 1.0 + 1.0, 0.0])


def test_vehicle_arc_is_a_circle_of_radius_v_over_w() -> None:
    v, w, dt = 10.0, 0.5, 0.4
    T = vehicle_arc(v, w, dt)
    radius = v / w
    centre = np.array([0.0, radius])
    assert abs(np.linalg.norm(T[:2, 3] - centre) - radius) < 1e-12
    assert abs(math.atan2(T[1, 0], T[0, 0]) - w * dt) < 1e-12
    np.testing.assert_allclose(vehicle_arc(v, 0.0, dt)[:3, 3], [v * dt, 0.0, 0.0], atol=1e-15)


def sample(t: float, speed: float = 10.0, yaw: float = 0.0, pan: float = 0.0, **kw: object
           ) -> SensorSample:
    return SensorSample(t=t, speed_m_s=speed, yaw_rate_rad_s=yaw, pan_rad=pan, **kw)  # type: ignore[arg-type]


def test_prior_of_straight_driving_is_forward_translation_without_rotation(default_config: Config) -> None:
    cfg = default_config
    p = prior_motion(cfg.mount, cfg.refinement, sample(0.0), sample(0.1), 0.3)
    np.testing.assert_allclose(p.t_m, [0.0, 0.0, -1.0], atol=1e-12)   # 1 m along camera z
    np.testing.assert_allclose(p.theta, np.zeros(5), atol=1e-12)
    assert not p.standstill and not p.wide and p.metric


def test_prior_rotation_of_a_left_turn_and_a_left_pan_moves_the_scene_right(default_config: Config) -> None:
    cfg = default_config
    centre = np.array([[CAM.cx, CAM.cy]])
    turn = prior_motion(cfg.mount, cfg.refinement, sample(0.0, yaw=0.3), sample(0.1, yaw=0.3), 0.3)
    pan = prior_motion(cfg.mount, cfg.refinement, sample(0.0, speed=0.0),
                       sample(0.1, speed=0.0, pan=0.01), 0.3)
    for prior, angle in ((turn, 0.03), (pan, 0.01)):
        flow = g.rotational_flow(CAM, centre, prior.R)[0]
        assert flow[0] > 0.0 and abs(flow[0] - CAM.fx * math.tan(angle)) < 0.05
    assert pan.standstill and np.all(pan.t_m == 0.0)


def test_missing_or_nan_can_widens_the_prior_and_says_so(default_config: Config) -> None:
    cfg = default_config
    ok = prior_motion(cfg.mount, cfg.refinement, sample(0.0), sample(0.1), 0.3)
    stale = prior_motion(cfg.mount, cfg.refinement, sample(0.0, can_valid=False),
                         sample(0.1, can_valid=False), 0.3)
    nan = prior_motion(cfg.mount, cfg.refinement, sample(0.0, speed=math.nan, yaw=math.nan),
                       sample(0.1, speed=math.nan, yaw=math.nan), 0.3)
    for p in (stale, nan):
        assert p.wide and not p.metric and not p.standstill
        np.testing.assert_allclose(p.sigma, ok.sigma * WIDE_PRIOR_FACTOR)
        assert np.all(np.isfinite(p.theta)) and np.all(np.isfinite(p.R))
    np.testing.assert_allclose(nan.theta[:2], [0.0, 0.0], atol=1e-12)   # assumes straight ahead
