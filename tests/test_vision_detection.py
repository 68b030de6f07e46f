"""Section 2: likelihood cues (eqs. 5-6, flow length, standstill) and the particle filter (figs. 3-4)."""

from __future__ import annotations

import math

import filterpy.monte_carlo.resampling as fp_resampling
import numpy as np
import pytest
from filterpy.monte_carlo import systematic_resample as filterpy_systematic

from appliance.config import Config, DetectionConfig
from appliance.vision import geometry as g
from appliance.vision.detection import (
    BIRTH_LIKELIHOOD,
    BIRTHS_PER_POINT,
    WEIGHT_FLOOR,
    ImportanceDensity,
    birth_positions,
    resample_particles,
    systematic_resample,
)
from appliance.vision.likelihood import (
    EPIPOLE_RADIUS_PX,
    CameraMotion,
    Cues,
    RoadPlane,
    combine,
    direction_cue,
    foot_points,
    magnitude_cue,
    motion_cues,
    road_depth,
    road_static_flow,
    standstill_cue,
)

CAM = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
K = CAM.K
HEIGHT = 1.3
ROAD = RoadPlane(normal=np.array([0.0, -1.0, 0.0]), height_m=HEIGHT)   # level camera
FORWARD = np.array([0.0, 0.0, -1.0])


def forward_motion(step_m: float = 0.4) -> CameraMotion:
    return CameraMotion(R=np.eye(3), t_dir=FORWARD, t_m=FORWARD * step_m, standstill=False, K=K)


def test_eq6_is_lowest_at_alpha_zero_rises_with_alpha_and_stays_in_0_1(default_config: Config) -> None:
    cfg = default_config.detection
    alphas = np.linspace(0.0, math.pi, 50)
    static_dir = np.tile([[1.0, 0.0]], (50, 1))
    d_e = np.full(50, 200.0)
    for length in (0.6, 2.0, 20.0):          # sigma_l from ~1 rad down to ~0.06 rad
        flow = length * np.column_stack([np.cos(alphas), np.sin(alphas)])
        p = direction_cue(flow, static_dir, d_e, cfg)
        assert p[0] == pytest.approx(0.0, abs=1e-12)
        rising = np.diff(p)
        assert np.all(rising >= 0.0)
        assert np.all(rising[p[1:] < 1.0 - 1e-9] > 0.0)   # strictly, until it saturates at 1
        assert np.all((p >= 0.0) & (p <= 1.0))
    # eq. 6 as printed would be negative here: sigma_l < 1/sqrt(2 pi)
    sigma_l = math.asin(cfg.sigma_e_px / 200.0) + math.asin(cfg.sigma_p_px / 20.0)
    assert sigma_l < 1.0 / math.sqrt(2.0 * math.pi)
    assert 1.0 - 1.0 / (math.sqrt(2.0 * math.pi) * sigma_l) < 0.0


def test_direction_is_undefined_near_the_epipole_and_for_near_zero_flow(default_config: Config) -> None:
    cfg = default_config.detection
    backwards = np.array([[-5.0, 0.0], [-0.05, 0.0], [0.0, 0.0], [-5.0, 0.0]])
    static_dir = np.tile([[1.0, 0.0]], (4, 1))
    d_e = np.array([EPIPOLE_RADIUS_PX / 2, 200.0, 200.0, 200.0])
    p = direction_cue(backwards, static_dir, d_e, cfg)
    np.testing.assert_allclose(p[:3], 0.0)   # at the epipole, a 0.05 px flow, a zero flow
    assert p[3] > 0.9                        # the same backwards flow far from the epipole


def test_road_depth_and_horizon_of_a_level_camera() -> None:
    uv = np.array([[319.5, 239.5 + 70.0], [100.0, 239.5 + 35.0], [319.5, 200.0]])
    Z = road_depth(ROAD, K, uv)
    np.testing.assert_allclose(Z[:2], [HEIGHT * 10.0, HEIGHT * 20.0])
    assert np.isnan(Z[2])                       # above the horizon: no road
    pitched = RoadPlane(normal=g.rot_x(-0.05).T @ np.array([0.0, -1.0, 0.0]), height_m=HEIGHT)
    # a camera pitched down (rotation about x by -0.05) sees the horizon higher
    v_h = 239.5 - 700.0 * math.tan(0.05)
    Z = road_depth(pitched, K, np.array([[319.5, v_h + 1.0], [319.5, v_h - 1.0]]))
    assert Z[0] > 500.0 and np.isnan(Z[1])


def road_correspondence(uv_cur: np.ndarray, step_m: float) -> np.ndarray:
    """Previous positions of the road points seen at uv_cur after moving step_m forward."""
    Z = road_depth(ROAD, K, uv_cur)
    X = np.column_stack([(uv_cur[:, 0] - K[0, 2]) / K[0, 0] * Z,
                         (uv_cur[:, 1] - K[1, 2]) / K[1, 1] * Z, Z])
    return CAM.project(X + np.array([0.0, 0.0, step_m]))


def test_magnitude_cue_flags_flow_much_shorter_than_the_road_allows(default_config: Config) -> None:
    cfg = default_config.detection
    uv = np.array([[420.0, 300.0], [420.0, 300.0], [420.0, 300.0], [420.0, 150.0]])
    x_prev = road_correspondence(uv[:3], 0.4)
    static_flow = uv[0] - x_prev[0]
    assert np.linalg.norm(static_flow) > 1.5
    flow_t = np.vstack([static_flow,              # a road point
                        1.5 * static_flow,        # closer than the road: a static obstacle
                        0.05 * static_flow,       # nearly no flow: on a collision course
                        [0.0, 0.0]])              # above the horizon
    p = magnitude_cue(flow_t, uv, forward_motion(), ROAD, cfg)
    assert p[0] < 0.05 and p[1] == 0.0
    assert p[2] > 0.8
    assert p[3] == 0.0
    unknown = CameraMotion(np.eye(3), FORWARD, None, False, K)   # CAN lost: no metric step
    np.testing.assert_array_equal(magnitude_cue(flow_t, uv, unknown, ROAD, cfg), 0.0)


def test_foot_point_is_the_bottom_of_the_run_the_pixel_stands_on() -> None:
    p = np.zeros((12, 4))          # map at 1/4: 48 x 16 px
    p[5:9, 1] = 0.8                # an object in column 1, cells 5-8 (px 20-35)
    p[2:4, 2] = 0.8                # a blob in column 2 with nothing below
    uv = np.array([[5.0, 22.0],    # inside the object's run
                   [6.0, 14.0],    # 6 px above its top (cell 3, run starts at cell 5: 8 px)
                   [6.0, 2.0],     # far above it: a facade, not the object
                   [5.0, 40.0],    # below it
                   [9.0, 0.0],     # column 2: the run below starts 8 px down, ends at cell 3
                   [13.0, 5.0]])   # column 3: no run
    feet = foot_points(p, 4, uv, 0.5, 48, gap_px=8.0)
    np.testing.assert_allclose(feet[:2], [[5.0, 35.0], [6.0, 35.0]])
    assert np.all(np.isnan(feet[2:4]))
    np.testing.assert_allclose(feet[4], [9.0, 15.0])
    assert np.all(np.isnan(feet[5]))
    tight = foot_points(p, 4, uv, 0.5, 48, gap_px=0.0)   # only pixels inside a run
    assert np.isnan(tight[1, 0]) and tight[0, 1] == 35.0


def test_a_pixel_above_the_horizon_takes_the_depth_of_its_foot_point(default_config: Config) -> None:
    foot = np.array([[420.0, 239.5 + 35.0]] * 3)            # road at 26 m
    uv = np.array([[420.0, 239.5 + 10.0],                    # below the horizon: its own road
                   [420.0, 239.5 - 20.0],                    # 1.3 + 26 * 20/700 = 2.04 m up
                   [420.0, 239.5 - 10.0]])                   # 1.67 m up
    motion = forward_motion()
    plain = road_static_flow(uv, motion, ROAD)
    assert np.all(np.isnan(plain[1:]))                       # no road behind: no bound
    with_foot = road_static_flow(uv, motion, ROAD, foot, max_height_m=2.0)
    np.testing.assert_allclose(with_foot[0], plain[0])
    assert np.isnan(with_foot[1, 0])                         # taller than a road user
    Z = HEIGHT * 20.0                                        # 26 m: the foot's depth
    expected = (K @ motion.t_m)[:2] - motion.t_m[2] * uv[2]
    np.testing.assert_allclose(with_foot[2], expected / (Z - motion.t_m[2]))
    # a head that keeps its bearing (no flow) is independent motion once its foot is known
    cfg = default_config.detection
    still = np.zeros((3, 2))
    plain_cues = motion_cues(uv - still, uv, motion, ROAD, cfg)
    foot_cues = motion_cues(uv - still, uv, motion, ROAD, cfg, foot=foot)
    assert plain_cues.magnitude is not None and foot_cues.magnitude is not None
    assert plain_cues.magnitude[2] == 0.0 and foot_cues.magnitude[2] > 0.8


def test_standstill_cue_is_half_at_the_configured_residual(default_config: Config) -> None:
    cfg = default_config.detection
    r0 = cfg.standstill_residual_px
    p = standstill_cue(np.array([[0.0, 0.0], [r0, 0.0], [0.0, 4.0 * r0]]), cfg)
    np.testing.assert_allclose(p, [0.0, 0.5, 1.0 - 2.0**-16])


def test_motion_cues_of_a_static_road_and_a_crossing_object(default_config: Config) -> None:
    cfg = default_config.detection
    uv = np.array([[500.0, 320.0], [150.0, 300.0], [500.0, 320.0]])
    x_prev = road_correspondence(uv, 0.4)
    x_prev[2] = uv[2] + np.array([3.0, 0.0])      # moved 3 px towards the epipole: crossing
    cues = motion_cues(x_prev, uv, forward_motion(), ROAD, cfg)
    assert cues.direction is not None and cues.magnitude is not None
    w = combine(cues, "combined")
    assert w[0] < 0.05 and w[1] < 0.05 and w[2] > 0.9
    standing = CameraMotion(np.eye(3), np.zeros(3), None, True, K)
    still = motion_cues(x_prev, uv, standing, ROAD, cfg)
    assert still.direction is None and still.standstill is not None
    np.testing.assert_array_equal(combine(still, "direction"), still.standstill)


def test_combine_modes() -> None:
    cues = Cues(direction=np.array([0.5, 0.0]), magnitude=np.array([0.5, 1.0]), standstill=None)
    np.testing.assert_allclose(combine(cues, "direction"), [0.5, 0.0])
    np.testing.assert_allclose(combine(cues, "magnitude"), [0.5, 1.0])
    np.testing.assert_allclose(combine(cues, "combined"), [0.75, 1.0])
    with pytest.raises(ValueError):
        combine(cues, "nonsense")


@pytest.mark.parametrize("offset", [0.0, 0.37, 0.999])
def test_systematic_resample_matches_filterpy(monkeypatch: pytest.MonkeyPatch, offset: float) -> None:
    w = np.random.default_rng(1).random(40)
    w /= w.sum()
    monkeypatch.setattr(fp_resampling, "random", lambda *a: offset)
    np.testing.assert_array_equal(systematic_resample(w, 40, offset), filterpy_systematic(w))


def test_with_no_valid_particle_all_come_from_g(default_config: Config) -> None:
    cfg = default_config.detection
    n = cfg.particles
    x = np.zeros((n, 2))
    out = resample_particles(x, np.ones(n), np.zeros(n, bool), ImportanceDensity(640, 480), cfg,
                             np.random.default_rng(0))
    assert out.shape == (n, 2)
    assert out[:, 0].std() > 100.0           # spread over the image, not stuck at (0, 0)


def static_flow_field(uv: np.ndarray, step_m: float) -> np.ndarray:
    """Previous positions of static points seen at uv: road below the horizon, a wall at 40 m above."""
    Z = road_depth(ROAD, K, uv)
    Z = np.where(np.isfinite(Z) & (Z < 40.0), Z, 40.0)
    X = np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0] * Z, (uv[:, 1] - K[1, 2]) / K[1, 1] * Z, Z])
    return CAM.project(X + np.array([0.0, 0.0, step_m]))


BLOB = (400.0, 200.0, 460.0, 290.0)   # u0, v0, u1, v1 px: an object standing on the road ~17 m ahead


def in_blob(uv: np.ndarray) -> np.ndarray:
    return (uv[:, 0] >= BLOB[0]) & (uv[:, 0] <= BLOB[2]) & (uv[:, 1] >= BLOB[1]) & (uv[:, 1] <= BLOB[3])


@pytest.mark.parametrize(("mode", "blob_flow"), [
    ("direction", np.array([-2.5, 0.0])),     # crossing towards the centre of the image
    ("magnitude", np.array([0.1, 0.05])),      # constant bearing: it only grows a little
    ("combined", np.array([0.1, 0.05])),
])
def test_particles_concentrate_on_a_moving_blob_within_a_few_frames(
        default_config: Config, mode: str, blob_flow: np.ndarray) -> None:
    """The paper's resampling (the default floor is small) gathers the particles in 3-5 frames."""
    cfg = default_config.with_overrides({"detection": {"likelihood": mode}}).detection
    final_share, shares = run_blob_filter(cfg, blob_flow, 5)
    assert final_share > 0.5, (mode, final_share)
    assert shares[-1] > 0.8                  # high-weight particles are on the blob


@pytest.mark.parametrize(("mode", "blob_flow"), [
    ("direction", np.array([-2.5, 0.0])),
    ("combined", np.array([0.1, 0.05])),
])
def test_a_high_weight_floor_gathers_more_slowly(
        default_config: Config, mode: str, blob_flow: np.ndarray) -> None:
    """A weight floor of 0.4 trades speed of gathering for fewer clumps on false evidence."""
    cfg = default_config.with_overrides({"detection": {"likelihood": mode}}).detection
    blob_share = (BLOB[2] - BLOB[0]) * (BLOB[3] - BLOB[1]) / (640 * 480)
    assert run_blob_filter(cfg, blob_flow, 5, 0.4)[0] < 0.5 * run_blob_filter(cfg, blob_flow, 5)[0]
    final_share, shares = run_blob_filter(cfg, blob_flow, 12, 0.4)
    assert final_share > 5.0 * blob_share, (mode, final_share)
    assert shares[-1] > 0.8


def run_blob_filter(cfg: DetectionConfig, blob_flow: np.ndarray, frames: int,
                    weight_floor: float = WEIGHT_FLOOR) -> tuple[float, list[float]]:
    """Particle filter on the synthetic flow field; share of particles on the blob at the end,
    and per frame the share of high-weight particles on the blob."""
    rng = np.random.default_rng(4)
    gd = ImportanceDensity(640, 480)
    particles = gd.sample(rng, cfg.particles)
    motion = forward_motion(0.4)
    shares: list[float] = []
    for _ in range(frames):
        # the scene and the blob stay put in this test: measure the flow ending at the particles
        x_cur = particles
        x_prev = static_flow_field(x_cur, 0.4)
        inside = in_blob(x_cur)
        x_prev[inside] = x_cur[inside] - blob_flow
        x_prev += rng.normal(0.0, 0.05, x_prev.shape)          # LK noise
        w = combine(motion_cues(x_prev, x_cur, motion, ROAD, cfg), cfg.likelihood)
        high = w > 0.5
        shares.append(float(in_blob(x_cur[high]).mean()) if high.any() else 0.0)
        valid = np.ones(len(x_cur), bool)
        particles = resample_particles(x_cur, w, valid, gd, cfg, rng, weight_floor=weight_floor)
    return float(in_blob(particles).mean()), shares


def test_no_evidence_where_the_road_flow_is_beyond_the_reach_of_lk(default_config: Config) -> None:
    cfg = default_config.detection
    uv = np.array([[600.0, 470.0], [420.0, 300.0]])      # bottom corner, middle distance
    x_prev = road_correspondence(uv, 0.6)
    road_flow = np.linalg.norm(uv - x_prev, axis=1)
    assert road_flow[0] > cfg.max_flow_px > road_flow[1]
    x_prev_stuck = uv - 0.1 * (uv - x_prev)               # LK lost the big flow: 10 % of it
    cues = motion_cues(x_prev_stuck, uv, forward_motion(0.6), ROAD, cfg)
    assert cues.direction is not None and cues.magnitude is not None
    assert cues.magnitude[0] == 0.0 and cues.direction[0] == 0.0
    assert cues.magnitude[1] > 0.5                         # the same deficit in reach is evidence


def test_particles_leaving_the_image_are_redrawn_not_piled_at_the_border(default_config: Config) -> None:
    cfg = default_config.with_overrides({"detection": {"importance_fraction": 0.0}}).detection
    n = cfg.particles
    x = np.tile([[639.0, 479.0]], (n, 1))                  # all in the corner, high weight
    out = resample_particles(x, np.ones(n), np.ones(n, bool), ImportanceDensity(640, 480), cfg,
                             np.random.default_rng(0))
    assert np.all((out >= 0.0) & (out <= [639.0, 479.0]))
    near_corner = np.hypot(out[:, 0] - 639.0, out[:, 1] - 479.0) < 10.0
    assert 0.1 < near_corner.mean() < 0.5                  # about the quarter that stayed inside


def test_flows_measured_along_an_edge_do_not_flag_motion(default_config: Config) -> None:
    """A flow known only across the static direction (a lane marking pointing at the epipole)
    says nothing about its length; one known only along it (a bumper) nothing about its angle."""
    cfg = default_config.detection
    uv = np.array([[420.0, 300.0], [420.0, 300.0]])
    x_prev = road_correspondence(uv, 0.4)
    static_flow = uv[0] - x_prev[0]
    d = static_flow / np.linalg.norm(static_flow)
    n = np.array([-d[1], d[0]])
    short = uv - 0.05 * static_flow                  # 5 % of the road's flow: collision course?
    skew = uv - np.linalg.norm(static_flow) * (0.5 * d + 0.866 * n)   # 60 degrees off the static direction

    def cov(along: float, across: float) -> np.ndarray:
        C = along * np.outer(d, d) + across * np.outer(n, n)
        return np.tile([C[0, 0], C[0, 1], C[1, 1]], (2, 1))

    sharp = cov(1e-4, 1e-4)
    along_edge = cov(100.0, 1e-4)    # the flow's length is not measured
    across_edge = cov(1e-4, 100.0)   # its angle is not
    for c, mag, direc in ((sharp, True, True), (along_edge, False, True), (across_edge, True, False)):
        m = motion_cues(short, uv, forward_motion(), ROAD, cfg, c)
        s = motion_cues(skew, uv, forward_motion(), ROAD, cfg, c)
        assert m.magnitude is not None and s.direction is not None
        assert (m.magnitude[0] > 0.8) == mag and (m.magnitude[0] < 0.05) == (not mag)
        assert (s.direction[0] > 0.8) == direc and (s.direction[0] < 0.05) == (not direc)
    # no covariance: every flow gets sigma_p, as in the paper
    paper = motion_cues(short, uv, forward_motion(), ROAD, cfg, None)
    assert paper.magnitude is not None and paper.magnitude[0] > 0.8


def test_births_gather_next_to_static_correspondences_that_look_independent(
        default_config: Config) -> None:
    """Static-pool corners with a high likelihood seed births next to them, at most
    BIRTHS_PER_POINT each, in proportion to the likelihood; none seed without. Births take the
    first importance slots."""
    cfg = default_config.detection
    rng = np.random.default_rng(3)
    corners = np.array([[100.0, 100.0], [400.0, 250.0], [600.0, 50.0]])
    lik = np.array([0.1, 0.9, 0.6])
    b = birth_positions(corners, lik, 50, BIRTH_LIKELIHOOD, 3.0, 640, 480, rng)
    assert len(b) == 2 * BIRTHS_PER_POINT                       # two corners above 0.5
    near = np.linalg.norm(b[:, None, :] - corners[None, :, :], axis=2).argmin(axis=1)
    assert set(near.tolist()) <= {1, 2}
    assert np.all(np.linalg.norm(b - corners[near], axis=1) < 15.0)
    assert len(birth_positions(corners, lik * 0.5, 50, BIRTH_LIKELIHOOD, 3.0, 640, 480, rng)) == 0
    many = birth_positions(corners, lik, 4000, 0.5, 3.0, 640, 480, rng)  # cap lifted by n
    assert len(many) == 2 * BIRTHS_PER_POINT
    edge = birth_positions(np.array([[0.0, 479.0]]), np.ones(1), 4, 0.5, 30.0, 640, 480, rng)
    assert np.all((edge >= 0.0) & (edge <= [639.0, 479.0]))

    n = cfg.particles
    x = rng.uniform([0, 0], [640, 480], (n, 2))
    out = resample_particles(x, np.full(n, 0.1), np.ones(n, bool), ImportanceDensity(640, 480),
                             cfg, rng, b)
    n_imp = round(cfg.importance_fraction * n)
    born = out[n - n_imp:n - n_imp + len(b)]
    np.testing.assert_array_equal(born, b)
