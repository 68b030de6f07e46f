"""The foot of a tracked object below its cluster (decision/foot_search.py) on rendered pairs.

A textured road is rendered through the camera before and after the car drives 0.5 m; a
pedestrian 10 m ahead walks 4 px to the side between the frames. Its body is solid, its legs
two thin bars with the road between them; the track's cluster ends at its hips, as on a
pedestrian whose legs' flows fail the forward-backward check. Vision measures the probe's
flows (vision/probes.py); the road's flow is known from the camera motion.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from appliance.config import load_config
from appliance.decision.foot_search import foot_probe, foot_row, road_flow
from appliance.decision.ground_state import CameraPose
from appliance.vision.geometry import PinholeCamera
from appliance.vision.probes import measure_points

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
POSE = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
TRAVEL_M = 0.5
PED_X, PED_Y = 12.0, 0.5             # m, the pedestrian's foot in the vehicle frame
DEPTH = PED_X - POSE.position[0]
FOOT_V = CAM.cy + CAM.fy * POSE.position[2] / DEPTH            # 329.6
HIPS_V = CAM.cy + CAM.fy * (POSE.position[2] - 0.9) / DEPTH     # 0.9 m up
TOP_V = CAM.cy + CAM.fy * (POSE.position[2] - 1.7) / DEPTH
CENTRE_U = CAM.cx - CAM.fx * PED_Y / DEPTH
HALF_W = 0.5 * 0.5 * CAM.fx / DEPTH                             # 0.5 m wide
WALK_PX = 4.0


def texture(seed: int, shape: tuple[int, int]) -> np.ndarray:
    noise = np.random.default_rng(seed).uniform(0, 255, shape).astype(np.float32)
    return np.clip(cv2.GaussianBlur(noise, (0, 0), 1.5) * 2.0 - 128.0, 0, 255).astype(np.uint8)


def road_image(camera_x: float) -> np.ndarray:
    """The road (texture 2 cm per px over x 4-44 m, y -10-10 m) seen from the camera at
    ``camera_x`` m along the vehicle's x axis."""
    res, x_max, y_max = 0.02, 44.0, 10.0
    tex = texture(1, (int(40 / res), int(20 / res)))
    C = np.array([camera_x, POSE.position[1], POSE.position[2]])
    # texture pixel (a, b) -> road point (x_max - res b, y_max - res a, 0), minus the camera
    A = np.array([[0.0, -res, x_max - C[0]], [-res, 0.0, y_max - C[1]], [0.0, 0.0, -C[2]]])
    H = CAM.K @ POSE.rotation().T @ A
    return cv2.warpPerspective(tex, H, (CAM.width, CAM.height), flags=cv2.INTER_LINEAR)


def with_pedestrian(img: np.ndarray, du: float) -> np.ndarray:
    """``img`` with the pedestrian pasted, shifted ``du`` px: a solid body down to the hips,
    below it two legs 6 px wide at the sides of its width, the road between them."""
    out = img.copy()
    body = texture(2, img.shape)
    u0, u1 = int(round(CENTRE_U - HALF_W + du)), int(round(CENTRE_U + HALF_W + du))
    top, hips, foot = int(round(TOP_V)), int(round(HIPS_V)), int(round(FOOT_V))
    src = np.roll(body, int(round(du)), axis=1)
    out[top:hips, u0:u1] = src[top:hips, u0:u1]
    for a, b in ((u0 + 2, u0 + 8), (u1 - 8, u1 - 2)):
        out[hips:foot, a:b] = src[hips:foot, a:b]
    return out


@pytest.fixture(scope="module")
def frames() -> tuple[np.ndarray, np.ndarray]:
    x_cur = POSE.position[0]
    prev = with_pedestrian(road_image(x_cur - TRAVEL_M), -WALK_PX)
    cur = with_pedestrian(road_image(x_cur), 0.0)
    return prev, cur


def translation() -> np.ndarray:
    """t of ``X_cur = R X_prev + t`` in the camera frame for the car driving TRAVEL_M."""
    return POSE.rotation().T @ np.array([-TRAVEL_M, 0.0, 0.0])


def find_foot(frames: tuple[np.ndarray, np.ndarray], v_bottom: float) -> float | None:
    prev, cur = frames
    box = (CENTRE_U - 0.6 * HALF_W, TOP_V, CENTRE_U + 0.6 * HALF_W, v_bottom)
    p = foot_probe(box, v_bottom, CAM, POSE)
    assert p is not None
    measured = measure_points(prev, cur, {"foot": p.points}, np.zeros(3), CAM,
                              load_config().flow)["foot"]
    road = road_flow(p.points, CAM, POSE, np.zeros(3), translation())
    return foot_row(p, measured.flow, measured.valid, road, CAM)


def test_road_flow_is_the_motion_of_road_points_between_two_camera_positions() -> None:
    pts = np.array([[12.0, 0.5, 0.0], [25.0, -3.0, 0.0], [6.0, 2.0, 0.0]])
    C = np.array(POSE.position)
    cur = CAM.project((pts - C) @ POSE.rotation())
    prev = CAM.project((pts - (C - [TRAVEL_M, 0.0, 0.0])) @ POSE.rotation())
    flow = road_flow(cur, CAM, POSE, np.zeros(3), translation())
    np.testing.assert_allclose(flow, cur - prev, atol=1e-6)
    above = road_flow(np.array([[320.0, 200.0]]), CAM, POSE, np.zeros(3), translation())
    assert np.all(np.isnan(above))


def test_the_foot_below_a_cluster_ending_at_the_hips_is_found(frames) -> None:
    foot = find_foot(frames, HIPS_V)
    assert foot is not None
    # within the Lucas-Kanade half window and a probe step of the true foot, 37 px below the hips
    assert abs(foot - FOOT_V) <= 8.0, (foot, FOOT_V)


def test_a_cluster_reaching_the_foot_keeps_its_bottom(frames) -> None:
    foot = find_foot(frames, FOOT_V + 1.0)
    assert foot is None or foot <= FOOT_V + 8.0


def test_nothing_measured_finds_no_foot() -> None:
    box = (CENTRE_U - HALF_W, TOP_V, CENTRE_U + HALF_W, HIPS_V)
    p = foot_probe(box, HIPS_V, CAM, POSE)
    assert p is not None
    n = len(p.points)
    road = road_flow(p.points, CAM, POSE, np.zeros(3), translation())
    assert foot_row(p, np.zeros((n, 2)), np.zeros(n, dtype=bool), road, CAM) is None


def test_the_search_stops_where_the_cluster_would_be_a_metre_above_the_foot() -> None:
    box = (CENTRE_U - HALF_W, TOP_V, CENTRE_U + HALF_W, HIPS_V)
    p = foot_probe(box, HIPS_V, CAM, POSE)
    assert p is not None
    # the cluster's bottom 1 m above the foot: the foot at H / (H - 1) of its drop below the horizon
    lowest = CAM.cy + (HIPS_V - CAM.cy) * 1.3 / 0.3
    assert p.rows[0] > HIPS_V and p.rows[-1] <= lowest
    assert p.rows[-1] >= FOOT_V
    assert foot_probe((300.0, 100.0, 340.0, 200.0), 200.0, CAM, POSE) is None   # above the horizon
