"""Per-flow noise (the forward-backward error in the flow std) and resampling."""

from __future__ import annotations

import numpy as np
import pytest

from appliance.config import Config
from appliance.vision.detection import ImportanceDensity, resample_particles
from appliance.vision.flow import FB_LENGTH_GAIN, fb_covariance
from appliance.vision.likelihood import CameraMotion, RoadPlane, motion_cues, road_static_flow

K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
ROAD = RoadPlane(normal=np.array([0.0, -1.0, 0.0]), height_m=1.3)
FORWARD = CameraMotion(R=np.eye(3), t_dir=np.array([0.0, 0.0, -1.0]),
                       t_m=np.array([0.0, 0.0, -0.3]), standstill=False, K=K)


def test_resampling_gathers_on_the_heavy_particle_within_the_diffusion(default_config: Config) -> None:
    cfg = default_config.with_overrides({"detection": {"particles": 200, "importance_fraction": 0.25}}
                                        ).detection
    n = cfg.particles
    x = np.column_stack([np.linspace(50, 590, n), np.full(n, 240.0)])
    likelihood = np.where(np.arange(n) == 17, 1.0, 0.0)      # one particle carries the weight
    out = resample_particles(x, likelihood, np.ones(n, bool), ImportanceDensity(640, 480), cfg,
                             np.random.default_rng(3), weight_floor=0.0)
    n_res = n - round(cfg.importance_fraction * n)
    offset = out[:n_res] - x[17]                             # all resampled from particle 17
    assert np.all(np.linalg.norm(offset, axis=1) < 5.0 * cfg.diffusion_px)
    assert np.std(offset) == pytest.approx(cfg.diffusion_px, rel=0.2)
    assert np.std(out[n_res:, 0]) > 100.0                    # the rest drawn from g


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
    cov = fb_covariance(fb, 20.0)
    cues = motion_cues(x_prev, uv, FORWARD, ROAD, cfg, cov)
    assert cues.direction is not None
    assert cues.direction[0] > 0.8 and cues.direction[1] < 0.5
    # an unchecked flow (NaN FB error) counts as error 0
    np.testing.assert_allclose(fb_covariance(np.array([np.nan, 0.1]), 20.0),
                               [[0.0, 0.0, 0.0], [4.0, 0.0, 4.0]])


def test_a_flow_at_a_motion_boundary_keeps_the_evidence_of_its_length(default_config: Config) -> None:
    """A flow whose forward-backward error is 0.3 px (its LK window holds a small mover and the
    road behind it) is no evidence by its direction, but a flow a tenth as long as the road's
    still is by its length: the length cue takes the smaller gain."""
    cfg = default_config.detection
    uv = np.array([[420.0, 330.0], [420.0, 330.0]])
    f_s = road_static_flow(uv, FORWARD, ROAD)
    d = f_s[0] / np.linalg.norm(f_s[0])
    n = np.array([-d[1], d[0]])
    x_prev = np.vstack([uv[0] - 0.1 * f_s[0],                                        # short
                        uv[1] - np.linalg.norm(f_s[0]) * (0.5 * d + 0.866 * n)])     # 60 deg off
    fb = np.full(2, 0.3)
    cues = motion_cues(x_prev, uv, FORWARD, ROAD, cfg, fb_covariance(fb), None,
                       fb_covariance(fb, FB_LENGTH_GAIN))
    assert cues.magnitude is not None and cues.direction is not None
    assert cues.magnitude[0] > 0.8
    assert cues.direction[1] < 0.5
    # with the direction's gain for the length too, the short flow would say little
    one_gain = motion_cues(x_prev, uv, FORWARD, ROAD, cfg, fb_covariance(fb))
    assert one_gain.magnitude is not None and one_gain.magnitude[0] < 0.5
