"""Spatio-temporal filter p(x) and clustering with eqs. 19-20 (section 4 of the paper)."""

from __future__ import annotations

import numpy as np
import pytest

from appliance.config import Config
from appliance.decision.clustering import (
    find_clusters,
    mean_probability,
    object_probability,
    weighted_mean_motion,
)
from appliance.decision.probability_map import (
    map_shape, spatial_probability, spatio_temporal_filter, warp_by_rotation,
)
from appliance.messages import ParticleSet, ProbabilityMap
from appliance.vision.geometry import PinholeCamera, matrix_to_euler, rot_y

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)


def particles(pos: list[tuple[float, float]], w: list[float],
              flow: list[tuple[float, float]] | None = None) -> ParticleSet:
    p = np.array(pos, dtype=float).reshape(-1, 2)
    f = np.zeros_like(p) if flow is None else np.array(flow, dtype=float).reshape(-1, 2)
    return ParticleSet(p, f, np.array(w, dtype=float), np.ones(len(p), dtype=bool), 9, 0.5)


def blob(center: tuple[float, float], n: int, w: float, spread: float = 12.0,
         seed: int = 0) -> ParticleSet:
    rng = np.random.default_rng(seed)
    pos = np.asarray(center) + rng.uniform(-spread, spread, (n, 2))
    return particles([tuple(p) for p in pos], [w] * n)


def test_eq19_eq20_hand_checked() -> None:
    flows = np.array([[2.0, 0.0], [4.0, 2.0], [0.0, -2.0]])
    s = np.array([0.5, 0.25, 0.25])
    # sum s f = (1 + 1 + 0, 0 + 0.5 - 0.5) = (2, 0); sum s = 1
    assert weighted_mean_motion(flows, s) == pytest.approx((2.0, 0.0))
    # sum s / N = 1 / 3
    assert mean_probability(s) == pytest.approx(1.0 / 3.0)
    s2 = np.array([0.6, 0.2, 0.2])  # (1.2 + 0.8 + 0, 0 + 0.4 - 0.4) / 1
    assert weighted_mean_motion(flows, s2) == pytest.approx((2.0, 0.0))
    s3 = np.array([0.0, 0.5, 0.5])  # (2 + 0, 1 - 1) / 1
    assert weighted_mean_motion(flows, s3) == pytest.approx((2.0, 0.0))
    s4 = np.array([1.0, 1.0, 0.0])  # (6, 2) / 2
    assert weighted_mean_motion(flows, s4) == pytest.approx((3.0, 1.0))
    assert mean_probability(s4) == pytest.approx(2.0 / 3.0)
    assert weighted_mean_motion(flows, np.zeros(3)) == (0.0, 0.0)
    assert mean_probability(np.zeros(0)) == 0.0


def test_lone_particle_and_normalised_convolution(default_config: Config) -> None:
    cfg = default_config.probability_map  # EVIDENCE_PARTICLES = 1, scale 4
    shape = map_shape(CAM, cfg.scale)
    p = spatial_probability(particles([(100.0, 100.0)], [1.0]), shape, cfg.scale, cfg)
    assert p[25, 25] == pytest.approx(0.5, abs=1e-3)  # w / (1 + evidence)
    assert p.max() == pytest.approx(p[25, 25]) and p.min() >= 0.0
    # a dense patch of low-weight (static) particles stays low, a patch of high weights is high
    low = spatial_probability(blob((300, 300), 80, 0.2), shape, cfg.scale, cfg)
    high = spatial_probability(blob((300, 300), 80, 0.9), shape, cfg.scale, cfg)
    assert 0.15 < low[75, 75] <= 0.2 and high[75, 75] > 0.8
    assert high.max() <= 1.0
    empty = spatial_probability(particles([], []), shape, cfg.scale, cfg)
    assert not np.any(empty)


def test_invalid_and_outside_particles_are_ignored(default_config: Config) -> None:
    cfg = default_config.probability_map
    ps = ParticleSet(np.array([[100.0, 100.0], [-5.0, 10.0], [700.0, 10.0], [np.nan, 3.0]]),
                     np.zeros((4, 2)), np.array([1.0, 1.0, 1.0, 1.0]),
                     np.array([False, True, True, True]), 9, 0.5)
    p = spatial_probability(ps, map_shape(CAM, cfg.scale), cfg.scale, cfg)
    assert not np.any(p)


def test_temporal_low_pass_bridges_a_one_frame_interruption(default_config: Config) -> None:
    cfg = default_config
    prob = None
    obj = blob((320, 300), 60, 0.9)
    n_clusters = []
    for k in range(12):
        ps = particles([], []) if k == 8 else obj  # a wiper hides the object in frame 8
        prob = spatio_temporal_filter(prob, ps, np.zeros(3), CAM, cfg.probability_map)
        n_clusters.append(len(find_clusters(prob, cfg.probability_map.scale, obj,
                                            cfg.clustering, (640, 480))))
    assert n_clusters[8] == 1 and all(n == 1 for n in n_clusters[1:])
    # without memory (alpha = 1) the interruption breaks the object
    no_mem = cfg.with_overrides({"probability_map": {"temporal_alpha": 1.0}})
    prob = spatio_temporal_filter(None, obj, np.zeros(3), CAM, no_mem.probability_map)
    prob = spatio_temporal_filter(prob, particles([], []), np.zeros(3), CAM, no_mem.probability_map)
    assert find_clusters(prob, 4, obj, no_mem.clustering, (640, 480)) == ()


def test_temporal_filter_is_a_first_order_low_pass(default_config: Config) -> None:
    cfg = default_config.probability_map
    obj = blob((320, 300), 60, 0.9)
    spatial = spatial_probability(obj, map_shape(CAM, cfg.scale), cfg.scale, cfg)
    prob = np.zeros_like(spatial)  # the decision state starts from an empty map
    for k in range(3):
        prob = spatio_temporal_filter(prob, obj, np.zeros(3), CAM, cfg)
    a = cfg.temporal_alpha
    np.testing.assert_allclose(prob, spatial * (1 - (1 - a) ** 3), rtol=1e-5, atol=1e-6)


def test_rotation_compensation_moves_the_map_with_the_camera(default_config: Config) -> None:
    cfg = default_config.probability_map
    prev = np.zeros(map_shape(CAM, cfg.scale), dtype=np.float32)
    prev[60, 80] = 1.0  # image pixel ~ (320, 240)
    # camera pans left by 0.02 rad (camera rotation Ry(-0.02), point rotation R = Ry(+0.02)):
    # static points move right by about fx * 0.02 = 14 px
    r = matrix_to_euler(rot_y(0.02))
    warped = warp_by_rotation(prev, r, CAM, cfg.scale)
    row, col = np.unravel_index(np.argmax(warped), warped.shape)
    assert row == 60 and col * cfg.scale == pytest.approx(320 + 14, abs=cfg.scale)


def test_clusters_boxes_counts_and_eq20_from_the_map(default_config: Config) -> None:
    cfg = default_config
    p = np.zeros(map_shape(CAM, 4), dtype=np.float32)
    p[50:60, 100:110] = 0.8  # image box u 400..440, v 200..240
    p[5:7, 5:7] = 0.9  # a small region with too few correspondences
    ps = particles(
        [(410, 210), (420, 220), (430, 230), (405, 236), (300, 300), (22, 22)],
        [0.9, 0.8, 0.7, 0.1, 0.9, 0.9],
        [(3, 1), (3, 1), (3, 1), (-1, 0), (5, 5), (0, 0)])
    clusters = find_clusters(p, 4, ps, cfg.clustering, (640, 480))
    assert len(clusters) == 1
    c = clusters[0]
    assert c.n == 4  # the four correspondences inside the region, not the one outside
    assert c.mean_probability == pytest.approx(0.8, abs=1e-6)  # eq. 20 with s_i = p(x_i)
    # eq. 19 with equal s_i: plain mean (3 + 3 + 3 - 1) / 4 = 2, (1 + 1 + 1 + 0) / 4 = 0.75
    assert c.mean_flow == pytest.approx((2.0, 0.75))
    # box spans the correspondences with weight >= MEMBER_WEIGHT (not the 0.1 one)
    assert c.bbox == (410.0, 210.0, 431.0, 231.0)
    # region box is the dilated region (larger than the 40 px block)
    assert c.region_bbox[0] < 400 and c.region_bbox[2] > 440


def test_eq20_of_a_narrow_object_is_taken_over_its_box_not_its_region(
        default_config: Config) -> None:
    """A pedestrian-wide object (8 px) in a region the blur and the dilation make three times
    as wide: the static scene beside it (p(x) 0.35 in the margin, above the threshold) is not
    the object's probability of independent motion."""
    cfg = default_config
    p = np.zeros(map_shape(CAM, 4), dtype=np.float32)
    p[48:62, 97:105] = 0.35                      # the blurred margin, u 388..420
    p[50:60, 100:102] = 0.85                     # the object, u 400..408, v 200..240
    u = [401.0, 403.0, 405.0, 407.0] * 3
    v = [205.0] * 4 + [220.0] * 4 + [235.0] * 4
    side_u = [390.0, 392.0, 414.0, 417.0] * 2
    side_v = [210.0] * 4 + [230.0] * 4
    ps = particles(list(zip(u + side_u, v + side_v)), [0.9] * 12 + [0.05] * 8)
    clusters = find_clusters(p, 4, ps, cfg.clustering, (640, 480))
    assert len(clusters) == 1
    c = clusters[0]
    assert c.n == 20
    assert mean_probability(c.s) == pytest.approx((12 * 0.85 + 8 * 0.35) / 20, abs=1e-6)
    assert c.mean_probability == pytest.approx(0.85, abs=1e-6)
    # fewer than two correspondences inside the box: the whole region's
    assert object_probability(c.positions, c.s, (0.0, 0.0, 1.0, 1.0)) == \
        pytest.approx(mean_probability(c.s))


def test_no_clusters_on_an_empty_map(default_config: Config) -> None:
    p = ProbabilityMap(np.zeros((120, 160), dtype=np.float32), 4)
    assert find_clusters(p.p, 4, particles([], []), default_config.clustering, (640, 480)) == ()
