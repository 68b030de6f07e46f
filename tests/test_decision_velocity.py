"""The velocity over ground across the line of sight: robust bearing-rate fit, its update of
the 3-D state, and the path prediction's velocity given an insignificant range rate.

Numbers from pedestrian_crossing_nearside (ego 9.72 m/s, adult crossing at 1.39 m/s, 32-42 m
ahead): from ground contacts alone the state said vx = +2.5 +- 3.4, vy = 0.42 +- 0.59 m/s when
the pedestrian was lost behind a parked car.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from appliance.config import Config
from appliance.decision.decide import _windowed_bearing_update
from appliance.decision.ground_state import GroundTrack, fit_bearing_rate
from appliance.decision.threat import significant_velocity
from appliance.messages import SensorSample

SPEED = 9.72  # m/s, ego
CAM_XY = (1.9, 0.0)


def crossing_bearings(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """t (s), bearing (rad, from the camera), cluster width (px) and the object's position (n, 2)
    for a pedestrian crossing at 1.39 m/s towards the ego path, 40 m ahead at t = 0, with
    1.5 mrad of bearing noise (a cluster centre about 1 px off)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0
    pos = np.column_stack([40.0 - SPEED * t, -5.6 + 1.39 * t])
    b = np.arctan2(pos[:, 1] - CAM_XY[1], pos[:, 0] - CAM_XY[0]) + rng.normal(0, 1.5e-3, n)
    w = np.full(n, 9.0) + rng.normal(0, 1.0, n)
    return t, b, w, pos


def true_rate(pos: np.ndarray) -> float:
    """The exact bearing rate (rad/s) at the last position."""
    x, y = pos[-1, 0] - CAM_XY[0], pos[-1, 1] - CAM_XY[1]
    return (x * 1.39 - y * (-SPEED)) / (x * x + y * y)


def test_bearing_rate_fit_leaves_out_a_cluster_cut_by_an_occluder() -> None:
    """The last 8 of 30 frames: an occluder covers the left of the object; the narrow
    remaining cluster's centre drifts right by up to 12 mrad (as measured on the nearside
    recordings). Theil-Sen on the frames of normal width keeps the rate; a least-squares
    fit over all frames (what a 10-frame polyfit does) is pulled far off."""
    t, b, w, pos = crossing_bearings(30, seed=1)
    cut = np.arange(22, 30)
    b[cut] -= np.linspace(1.5e-3, 12e-3, len(cut))
    w[cut] = 2.5
    fit = fit_bearing_rate(t, b, w, 0.6, 8)
    assert fit is not None
    assert fit.frames == 22
    assert fit.rate == pytest.approx(true_rate(pos), abs=3e-3)
    assert fit.std < 3e-3
    naive = float(np.polyfit(t, b, 1)[0])
    assert abs(naive - true_rate(pos)) > 8e-3
    # without the width test the cut frames bias the robust fit too
    all_frames = fit_bearing_rate(t, b, w, 0.0, 8)
    assert all_frames is not None and all_frames.frames == 30
    assert abs(all_frames.rate - true_rate(pos)) > abs(fit.rate - true_rate(pos))


def test_bearing_rate_fit_needs_enough_frames() -> None:
    t, b, w, _ = crossing_bearings(6, seed=2)
    assert fit_bearing_rate(t, b, w, 0.6, 8) is None
    assert fit_bearing_rate(t, b, w, 0.6, 5) is not None
    # no time span
    assert fit_bearing_rate(np.zeros(10), b[:1].repeat(10), np.ones(10), 0.6, 5) is None


def test_windowed_bearing_update_and_conditioning_recover_the_crossing_speed(
        default_config: Config) -> None:
    """The state the nearside recording had when its pedestrian was lost (vx +2.5 +- 3.4 m/s
    from a range bias, vy 0.42): the windowed bearing-rate update fixes the velocity across
    the line of sight; its vy alone is still pulled down by the noise value of vx, given
    vx = 0 (the range rate is insignificant) it is the true 1.39 m/s."""
    cfg = default_config.with_overrides({"ground": {"bearing_window_s": 1.0}})
    t, b, w, pos = crossing_bearings(30, seed=3)
    hist = tuple(zip(t.tolist(), b.tolist(), w.tolist()))
    P = np.diag([1.5, 0.05, 3.4 ** 2, 0.59 ** 2])
    g = GroundTrack(x=np.array([pos[-1, 0] - 1.5, pos[-1, 1], 2.5, 0.42]), P=P,
                    t_update=float(t[-1]), updates=31)
    sensors = SensorSample(float(t[-1]), SPEED, 0.0)
    g2 = _windowed_bearing_update(g, hist, sensors, cfg)
    d = g2.position - np.asarray(CAM_XY)
    brg = math.atan2(d[1], d[0])
    tangent = np.array([-math.sin(brg), math.cos(brg)])
    assert g2.velocity @ tangent == pytest.approx(np.array([0.0, 1.39]) @ tangent, abs=0.12)
    np.testing.assert_allclose(g2.position, g.position, atol=1e-9)
    sig = cfg.warning.velocity_significance_sigmas
    marginal = significant_velocity(g2.velocity, g2.P, sig, condition=False)
    given = significant_velocity(g2.velocity, g2.P, sig, condition=True)
    assert marginal[0] == 0.0 and given[0] == 0.0
    assert marginal[1] < 1.1  # 0 or pulled down by the noise value of vx
    assert given[1] == pytest.approx(1.39, abs=0.12)
    # too short a history: the state is unchanged
    assert _windowed_bearing_update(g, hist[:5], sensors, cfg) is g


def test_conditioning_on_a_zeroed_component() -> None:
    """E[vy | vx = 0] = vy - P_yx / P_xx vx; nothing changes when both or neither component
    is significant, or without correlation."""
    P = np.zeros((4, 4))
    P[2:, 2:] = [[4.0, -0.9], [-0.9, 0.25]]
    v = np.array([2.0, 0.6])
    # vy given vx = 0: 0.6 + 0.9 / 4 * 2 = 1.05, conditional std sqrt(0.25 - 0.81 / 4) = 0.22
    np.testing.assert_allclose(significant_velocity(v, P, 2.0, condition=True), [0.0, 1.05])
    # the marginal vy (0.6 +- 0.5) is insignificant as well: a crossing pedestrian stands still
    np.testing.assert_allclose(significant_velocity(v, P, 2.0, condition=False), [0.0, 0.0])
    both = np.array([0.1, 0.1])
    np.testing.assert_allclose(significant_velocity(both, P, 2.0, condition=True), [0.0, 0.0])
    big = np.array([9.0, 3.0])
    np.testing.assert_allclose(significant_velocity(big, P, 2.0, condition=True), big)
    Pd = np.diag([0.0, 0.0, 4.0, 0.25])
    np.testing.assert_allclose(significant_velocity(np.array([2.0, 1.2]), Pd, 2.0, condition=True),
                               [0.0, 1.2])
