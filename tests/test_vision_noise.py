"""Per-flow noise (LK covariance, aperture, forward-backward error) and lineage confirmation."""

from __future__ import annotations

import numpy as np

from appliance.config import Config
from appliance.vision.baseline import advance_history, inherit_history, lineage_weight
from appliance.vision.detection import ImportanceDensity, resample_particles
from appliance.vision.flow import flow_covariance, lk_covariance
from appliance.vision.likelihood import CameraMotion, RoadPlane, motion_cues

K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
ROAD = RoadPlane(normal=np.array([0.0, -1.0, 0.0]), height_m=1.3)
FORWARD = CameraMotion(R=np.eye(3), t_dir=np.array([0.0, 0.0, -1.0]),
                       t_m=np.array([0.0, 0.0, -0.3]), standstill=False, K=K)


def _streaks(seed: int = 0) -> np.ndarray:
    """Texture that varies along the rows only (horizontal streaks): u is not measurable."""
    rows = np.random.default_rng(seed).integers(40, 215, size=(120, 1))
    return np.repeat(rows, 160, axis=1).astype(np.uint8)


def _blobs(seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 255, size=(120, 160)).astype(np.uint8)


def test_lineage_weight_is_the_weakest_known_link() -> None:
    history = np.array([[0.9, 0.8], [0.9, 0.1], [np.nan, np.nan], [0.2, np.nan]])
    w = lineage_weight(np.array([0.7, 0.9, 0.6, 0.9]), history)
    np.testing.assert_allclose(w, [0.7, 0.1, 0.6, 0.2])
    # k = 1: the paper's one-frame weight
    np.testing.assert_allclose(lineage_weight(np.array([0.3]), np.zeros((1, 0))), [0.3])


def test_history_advances_drops_the_oldest_and_is_lost_with_an_invalid_flow() -> None:
    history = np.array([[0.5, 0.4], [0.3, 0.2]])
    new = advance_history(history, np.array([0.9, 0.8]), np.array([True, False]))
    np.testing.assert_allclose(new[0], [0.9, 0.5])
    assert np.all(np.isnan(new[1]))


def test_children_inherit_their_parents_history_and_samples_of_g_start_without() -> None:
    history = np.array([[0.9, 0.8], [0.1, 0.2]])
    out = inherit_history(history, np.array([1, 0, -1, 1]))
    np.testing.assert_allclose(out[[0, 1, 3]], history[[1, 0, 1]])
    assert np.all(np.isnan(out[2]))


def test_resampling_reports_parents_and_offsets(default_config: Config) -> None:
    cfg = default_config.with_overrides({"detection": {"particles": 200, "weight_floor": 0.0,
                                                        "importance_fraction": 0.25}}).detection
    n = cfg.particles
    x = np.column_stack([np.linspace(50, 590, n), np.full(n, 240.0)])
    likelihood = np.where(np.arange(n) == 17, 1.0, 0.0)      # one particle carries the weight
    out, corr, parent, offset = resample_particles(
        x, likelihood, np.ones(n, bool), np.ones(n), ImportanceDensity(640, 480), cfg,
        np.random.default_rng(3))
    resampled = parent >= 0
    assert resampled.sum() > 0.6 * n and np.all(parent[resampled] == 17)
    np.testing.assert_allclose(out[resampled], x[17] + offset[resampled])
    assert np.all(offset[~resampled] == 0.0)            # drawn from g: no parent, no offset
    assert np.all(corr[resampled] == 1.0)


def test_aperture_covariance_is_large_across_streaks_only() -> None:
    """image_noise^2 G^-1: on horizontal streaks the u component is unknown, v is known."""
    pts = np.array([[80.0, 60.0]])
    streaks = lk_covariance(_streaks(), pts, np.array([1.0]), 9, 0.0, 6.0)
    blobs = lk_covariance(_blobs(), pts, np.array([1.0]), 9, 0.0, 6.0)
    assert streaks is not None and blobs is not None
    assert streaks[0, 0] > 100.0 * streaks[0, 2]       # var(u) >> var(v)
    assert streaks[0, 0] > 100.0 * blobs[0, 0]
    # with every term off there is no covariance: the paper's constant sigma_p
    assert lk_covariance(_blobs(), pts, np.array([1.0]), 9, 0.0, 0.0) is None
    # the residual term alone is flow_covariance scaled by the gain squared
    res = lk_covariance(_blobs(), pts, np.array([2.0]), 9, 3.0, 0.0)
    np.testing.assert_allclose(res, 9.0 * flow_covariance(_blobs(), pts, np.array([2.0]), 9))


def test_forward_backward_error_widens_the_flow_std(default_config: Config) -> None:
    """A flow 40 degrees off the static direction flags motion unless its FB error says
    it is unreliable."""
    cfg = default_config.detection
    uv = np.array([[420.0, 330.0], [420.0, 330.0]])
    e = np.array([319.5, 239.5])
    d = (uv[0] - e) / np.linalg.norm(uv[0] - e)
    rot = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    x_prev = uv - 3.0 * (rot @ d)
    fb = np.array([0.01, 0.3])
    cov = lk_covariance(_blobs(), x_prev, np.ones(2), 9, 0.0, 0.0, fb, 20.0)
    assert cov is not None
    cues = motion_cues(x_prev, uv, FORWARD, ROAD, cfg, cov)
    assert cues.direction is not None
    assert cues.direction[0] > 0.8 and cues.direction[1] < 0.5
    # an unchecked flow (NaN FB error) counts as error 0
    cov_nan = lk_covariance(_blobs(), x_prev, np.ones(2), 9, 0.0, 0.0, np.array([np.nan, np.nan]), 20.0)
    assert cov_nan is not None and np.all(cov_nan == 0.0)
