"""The velocity over ground across the line of sight: the windowed fit through the track's
sightings, its update of the 3-D state, and the path prediction's velocity given an
insignificant range rate.

Numbers from pedestrian_crossing_nearside (ego 9.72 m/s, adult crossing at 1.39 m/s, 32-42 m
ahead): from ground contacts alone the state said vx = +2.5 +- 3.4, vy = 0.42 +- 0.59 m/s when
the pedestrian was lost behind a parked car.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from appliance.config import Config
from appliance.decision.crossing_velocity import (
    fit_crossing_velocity, odometry_step, to_odometry, windowed_crossing_update,
)
from appliance.decision.ground_state import GroundTrack

SPEED = 9.72  # m/s, ego
CAM_XY = (1.9, 0.0)
DT = 1.0 / 30.0


def sightings(obj0: tuple[float, float], vel: tuple[float, float], n: int, seed: int,
              yaw_rate: float = 0.0, noise: float = 1.5e-3
              ) -> tuple[np.ndarray, np.ndarray, tuple[float, float, float]]:
    """(n, 5) sightings (t, ray direction, camera x, y in the odometry frame, width px) of an
    object moving at ``vel`` over ground from ``obj0`` (odometry frame = vehicle frame at
    t = 0), the ego at SPEED along an arc of ``yaw_rate``; bearing noise ``noise`` rad (a
    cluster centre about 1 px off). Also the object's position in the last vehicle frame and
    the last odometry pose."""
    rng = np.random.default_rng(seed)
    odo = (0.0, 0.0, 0.0)
    rows = []
    for i in range(n):
        if i:
            odo = odometry_step(odo, SPEED, yaw_rate, DT)
        t = i * DT
        obj = np.asarray(obj0) + np.asarray(vel) * t
        cam = to_odometry(odo, np.asarray(CAM_XY))
        ray = math.atan2(obj[1] - cam[1], obj[0] - cam[0]) + rng.normal(0.0, noise)
        rows.append((t, ray, cam[0], cam[1], 9.0 + rng.normal(0.0, 1.0)))
    x, y, psi = odo
    c, s = math.cos(psi), math.sin(psi)
    d = obj - np.array([x, y])
    return np.array(rows), np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]), odo


def state(pos: np.ndarray, v: tuple[float, float], odo: tuple[float, float, float],
          P: np.ndarray | None = None) -> GroundTrack:
    """A 3-D state at ``pos`` (vehicle frame) with velocity ``v`` given in the odometry frame."""
    c, s = math.cos(odo[2]), math.sin(odo[2])
    vv = np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1]])
    P = np.diag([1.5, 0.05, 3.4 ** 2, 0.59 ** 2]) if P is None else P
    return GroundTrack(x=np.concatenate([pos, vv]), P=P, t_update=0.0, updates=31)


def truth_across(cv_tangent: np.ndarray, vel: tuple[float, float], psi: float) -> float:
    c, s = math.cos(psi), math.sin(psi)
    v = np.array([c * vel[0] + s * vel[1], -s * vel[0] + c * vel[1]])
    return float(cv_tangent @ v)


def test_crossing_velocity_from_the_bearings_despite_a_wrong_state() -> None:
    """A pedestrian 40 m ahead crossing at 1.39 m/s: the state's own velocity is the wrong one
    the contacts gave (2.5, 0.42) and its range 1.5 m short; the fit through the sightings
    still gives the velocity across the line of sight to a few cm/s."""
    vel = (0.0, 1.39)
    a, pos, odo = sightings((40.0, -5.6), vel, 30, seed=1)
    g = state(pos - np.array([1.5, 0.0]), (2.5, 0.42), odo)
    cv = fit_crossing_velocity(a, g, odo, CAM_XY, 0.6, 8)
    assert cv is not None and cv.frames >= 28
    assert cv.value == pytest.approx(truth_across(cv.tangent, vel, odo[2]), abs=0.08)
    assert cv.std < 0.08


def test_crossing_velocity_of_a_passing_pedestrian_does_not_lag() -> None:
    """A pedestrian passing 17 m ahead: its bearing rate grows by half within the 1 s window,
    so a straight line through the bearings gives the rate of the window's middle, about a
    quarter low; cutting each ray at its range does not."""
    vel = (0.0, 1.39)
    a, pos, odo = sightings((27.0, -1.7), vel, 30, seed=2)
    g = state(pos, vel, odo)
    cv = fit_crossing_velocity(a, g, odo, CAM_XY, 0.6, 8)
    assert cv is not None
    assert cv.value == pytest.approx(truth_across(cv.tangent, vel, odo[2]), abs=0.08)
    # the straight line through the bearings, with the ego part removed as velocity_prior does
    rate = float(np.polyfit(a[:, 0], a[:, 1], 1)[0])
    d = pos - np.asarray(CAM_XY)
    r, b = float(np.hypot(*d)), math.atan2(d[1], d[0])
    naive = r * rate - SPEED * math.sin(b)
    assert naive < 0.9 * truth_across(cv.tangent, vel, odo[2])


def test_crossing_velocity_in_a_bend_and_with_a_cut_cluster() -> None:
    """Ego yawing at 0.15 rad/s (the rays are in the odometry frame, so the turn is not
    motion); the last 8 frames have a cluster cut to a third by an occluder whose centre
    drifts by up to 12 mrad: they are left out."""
    vel = (0.0, 1.39)
    a, pos, odo = sightings((35.0, -5.0), vel, 30, seed=3, yaw_rate=0.15)
    a[22:, 1] -= np.linspace(1.5e-3, 12e-3, 8)
    a[22:, 4] = 3.0
    g = state(pos, (0.0, 0.0), odo)
    cv = fit_crossing_velocity(a, g, odo, CAM_XY, 0.6, 8)
    assert cv is not None and cv.frames == 22
    assert cv.value == pytest.approx(truth_across(cv.tangent, vel, odo[2]), abs=0.1)
    kept_all = fit_crossing_velocity(a, g, odo, CAM_XY, 0.0, 8)
    assert kept_all is not None and kept_all.frames == 30
    assert abs(kept_all.value - cv.value) > 0.1
    # too few frames, no time span
    assert fit_crossing_velocity(a[:6], g, odo, CAM_XY, 0.6, 8) is None
    flat = a[:10].copy()
    flat[:, 0] = 0.0
    assert fit_crossing_velocity(flat, g, odo, CAM_XY, 0.6, 8) is None


def test_windowed_update_recovers_the_velocity_across_the_line_of_sight() -> None:
    """The state the nearside recording had when its pedestrian was lost (vx +2.5 +- 3.4 m/s
    from a range bias, vy 0.42): after the windowed update the velocity across the line of
    sight is right, the position unchanged; a history shorter than the fit needs changes
    nothing."""
    vel = (0.0, 1.39)
    a, pos, odo = sightings((40.0, -5.6), vel, 30, seed=4)
    P = np.diag([1.5, 0.05, 3.4 ** 2, 0.59 ** 2])
    P[2, 3] = P[3, 2] = -0.5 * 3.4 * 0.59
    g = state(pos - np.array([1.5, 0.0]), (2.5, 0.42), odo, P)
    hist = tuple(tuple(float(x) for x in row) for row in a)
    g2 = windowed_crossing_update(g, hist, odo, CAM_XY)
    np.testing.assert_allclose(g2.position, g.position, atol=1e-9)
    los = g2.position - np.asarray(CAM_XY)
    tangent = np.array([-los[1], los[0]]) / np.hypot(*los)
    assert g2.velocity @ tangent == pytest.approx(np.array(vel) @ tangent, abs=0.1)
    assert abs(g.velocity @ tangent - np.array(vel) @ tangent) > 0.5
    assert windowed_crossing_update(g, hist[:5], odo, CAM_XY) is g
