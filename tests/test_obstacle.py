"""Anything standing in the path: depth from motion parallax (vision/parallax.py) and the
obstacle it makes (decision/obstacle.py), on synthetic points and on simulated drives."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from appliance.config import load_config
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import camera_pose
from appliance.decision.obstacle import (
    CONFIRM_FRAMES,
    ObstacleState,
    arc_coordinates,
    obstacle_step,
    time_to_contact,
)
from appliance.evaluation.report import evaluate_run
from appliance.messages import EgoMotion, SensorSample, StandingPoints
from appliance.pipeline import camera_from_config
from appliance.recording import Recording, apply_meta
from appliance.replay import replay
from appliance.sim.drive import simulate
from appliance.vision.geometry import euler_to_matrix
from appliance.vision.parallax import compose, triangulate

CFG = load_config()
CAMERA = camera_from_config(CFG)


def test_triangulation_gives_the_depth_of_static_points_and_flags_movers() -> None:
    rng = np.random.default_rng(1)
    P_then = np.column_stack([rng.uniform(-5, 5, 50), rng.uniform(-1, 1.3, 50),
                              rng.uniform(8, 60, 50)])
    R = euler_to_matrix(np.array([0.004, -0.01, 0.002]))
    t = np.array([0.02, 0.01, -4.0])                       # 4 m forward
    P_now = P_then @ R.T + t
    z, d = triangulate(P_then / P_then[:, 2:3], P_now / P_now[:, 2:3], R, t)
    assert np.allclose(z, P_now[:, 2], rtol=1e-9)
    assert np.all(d * CAMERA.fx < 1e-6)
    moved = P_now + np.array([0.5, 0.0, 0.0])              # 0.5 m sideways on its own
    _, d2 = triangulate(P_then / P_then[:, 2:3], moved / moved[:, 2:3], R, t)
    assert np.median(d2 * CAMERA.fx) > 1.0


def test_motions_compose_oldest_first() -> None:
    steps = [(euler_to_matrix(np.array([0.0, 0.01 * i, 0.0])), np.array([0.0, 0.0, -0.5 * i]))
             for i in range(1, 4)]
    X0 = np.array([1.0, -0.5, 30.0])
    X = X0
    for R, t in steps:
        X = R @ X + t
    R, t = compose(tuple(steps), 3)
    assert np.allclose(R @ X0 + t, X)
    assert compose(tuple(steps) + (None,), 2) is None


def test_arc_coordinates_follow_the_bend() -> None:
    k = 1.0 / 50.0                                         # left bend, radius 50 m
    a = np.array([0.2, 0.6])                               # rad along the arc
    on_arc = np.column_stack([np.sin(a) / k, (1 - np.cos(a)) / k])
    s, lat = arc_coordinates(on_arc, k)
    assert np.allclose(s, a / k) and np.allclose(lat, 0.0, atol=1e-9)
    s, lat = arc_coordinates(on_arc * np.array([1.0, 1.0]) + np.array([0.0, 1.0]), 0.0)
    assert np.allclose(lat, on_arc[:, 1] + 1.0)


def test_time_to_contact_with_and_without_braking() -> None:
    assert time_to_contact(30.0, 15.0, 0.0) == pytest.approx(2.0)
    assert time_to_contact(30.0, 15.0, -0.5) == pytest.approx(2.0)   # not braking: ignored
    assert time_to_contact(30.0, 15.0, -3.0) == pytest.approx((15 - math.sqrt(225 - 180)) / 3)
    assert time_to_contact(30.0, 10.0, -3.0) is None                  # stops after 16.7 m


def _frame(t: float, speed: float = 15.0) -> FrameContext:
    sensors = SensorSample(t=t, speed_m_s=speed, yaw_rate_rad_s=0.0)
    z = np.zeros(3)
    ego = EgoMotion(rotation=z, translation_dir=np.array([0.0, 0.0, -1.0]), epipole_px=None,
                    prior_rotation=z, prior_translation_dir=z, prior_epipole_px=None, inliers=100,
                    confident=True)
    return FrameContext(t=t, dt=1 / 30, pose=camera_pose(CFG.mount, 0.0, sensors),
                        sensors=sensors, ego=ego, odo=(0.0, 0.0, 0.0), camera=CAMERA,
                        mount=CFG.mount, window_px=CFG.flow.window_px, flow_std_px=0.5)


def _points(f: FrameContext, xs: np.ndarray, ys: np.ndarray, zs: np.ndarray) -> StandingPoints:
    """Vehicle-frame points seen from the frame's camera, 2 % depth std."""
    veh = np.column_stack([xs, ys, zs])
    cam = (veh - np.asarray(f.pose.position)) @ f.pose.rotation()
    return StandingPoints(pixels=CAMERA.project(cam), points=cam, depth_std=0.02 * cam[:, 2],
                          epipolar_px=np.zeros(len(cam)), baseline=np.full(len(cam), 12))


def _run(make, frames: int = 12, speed: float = 15.0):
    state, threat, next_id = ObstacleState(), None, 1
    prob = np.zeros((120, 160), dtype=np.float32)
    seen = []
    for i in range(frames):
        f = _frame(1000.0 + i / 30, speed)
        state, threat, next_id = obstacle_step(state, make(f, i), f, prob, 4, [], CFG.obstacle,
                                               CFG.warning, next_id)
        seen.append(threat)
    return seen


def _car_rear(x0: float, lateral: float = 0.0, low: float = 0.4, high: float = 1.4):
    u = np.linspace(-0.8, 0.8, 5)
    h = np.linspace(low, high, 3)
    yy, zz = np.meshgrid(u + lateral, h)

    def make(f: FrameContext, i: int) -> StandingPoints:
        x = x0 - f.speed * i / 30
        return _points(f, np.full(yy.size, x), yy.ravel(), zz.ravel())
    return make


def test_a_car_standing_in_the_lane_is_confirmed_with_its_time_to_contact() -> None:
    seen = _run(_car_rear(40.0))
    assert all(th is None for th in seen[:CONFIRM_FRAMES - 1])
    th = seen[-1]
    assert th is not None and th.standing and th.max_level == 2
    gap = 40.0 - 15.0 * 11 / 30 - CFG.mount.vehicle_front_m
    assert th.report.distance_m == pytest.approx(gap, rel=0.03)
    assert th.ttc == pytest.approx(gap / 15.0, rel=0.03)


def test_nothing_stands_on_the_road_or_above_the_car_or_beside_the_path() -> None:
    assert all(th is None for th in _run(_car_rear(40.0, low=0.0, high=0.1)))    # road marking
    assert all(th is None for th in _run(_car_rear(40.0, low=3.0, high=4.0)))    # a bridge
    assert all(th is None for th in _run(_car_rear(40.0, lateral=3.5)))          # next lane


def test_an_obstacle_at_the_edge_of_the_path_raises_a_caution_at_most() -> None:
    th = _run(_car_rear(40.0, lateral=-1.3))[-1]      # its inner half in the corridor
    assert th is not None and th.max_level == 1


def _drive(tmp: Path, scenario: str) -> tuple[dict, list[dict]]:
    rec_dir = simulate(scenario, tmp / "rec", seed=1)
    rec = Recording(rec_dir, defaults=CFG)
    replay(rec, apply_meta(CFG, rec.meta), tmp / "run")
    warnings = [json.loads(x) for x in (tmp / "run" / "warnings.jsonl").read_text().splitlines()]
    return evaluate_run(rec_dir, tmp / "run", plot=False), warnings


@pytest.mark.slow
def test_a_car_stopped_in_the_lane_is_warned_of_in_time(tmp_path: Path) -> None:
    result, warnings = _drive(tmp_path, "car_stopped_in_lane_30")
    assert result["lead_time_s"] is not None and result["lead_time_s"] >= 1.5
    assert result["false_level2"] == 0
    first = min(w["t"] for w in warnings if w["level"] >= 1)
    assert result["collision_t"] - first >= 2.4


@pytest.mark.slow
def test_a_car_standing_in_the_next_lane_is_not_warned_of(tmp_path: Path) -> None:
    result, warnings = _drive(tmp_path, "car_stopped_next_lane")
    assert not any(w["level"] == 2 for w in warnings)
    assert result["false_level2"] == 0
