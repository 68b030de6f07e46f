"""Where a tracked object meets the road (``object_foot.py``, ``cues/foot.py``): the flow
followed down the image from a cluster that sits on the object's hips, measured by vision's
Lucas-Kanade on a ray-cast scene (a textured road, the camera driving forward, an upright
textured object keeping its bearing: a pedestrian on a collision course)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from appliance.config import Config, load_config
from appliance.decision.frame import FrameContext, lowered_contact
from appliance.decision.ground_state import CameraPose, GroundModel, ground_contact
from appliance.decision.clustering import Cluster
from appliance.decision.object_foot import Foot, foot, foot_probe, road_flow
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import PinholeCamera
from appliance.vision.probes import measure_points

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
POSE = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
HEIGHT_M = 1.3
TRAVEL_M = 0.4                      # per frame, forward (36 km/h at 25 frames/s)
MOTION = (np.eye(3), np.array([0.0, 0.0, -TRAVEL_M]))   # X_cur = R X_prev + t


def _texture(seed: int, blur: float, size: int = 1024) -> np.ndarray:
    noise = np.random.default_rng(seed).uniform(0, 255, (size, size)).astype(np.float32)
    t = cv2.GaussianBlur(noise, (0, 0), blur)
    return np.clip((t - t.mean()) * 60.0 / t.std() + 128.0, 0, 255).astype(np.float32)


ROAD = _texture(1, 1.5)      # 60 texture px per m across the road, 6.5 along it: at 12 m
BODY = _texture(2, 1.2)      #   about one per image px both ways; 60 per m of the object


def render(depth_m: float, lateral_m: float, travelled_m: float, width_m: float = 0.6,
           height_m: float = 1.7, legs: bool = False, swing_m: float = 0.0) -> np.ndarray:
    """The camera's image: the road (texture fixed on the ground, the camera ``travelled_m``
    along it) and an upright object ``width_m`` wide and ``height_m`` tall standing on it,
    ``depth_m`` ahead and ``lateral_m`` right (camera frame). With ``legs`` its lower half is
    two legs with road between them; ``swing_m`` moves its left leg that far to the left of
    where the body carries it (a leg swinging forward while the body walks on)."""
    u, v = np.meshgrid(np.arange(CAM.width, dtype=np.float64),
                       np.arange(CAM.height, dtype=np.float64))
    rx, ry = (u - CAM.cx) / CAM.fx, (v - CAM.cy) / CAM.fy
    # road: camera-frame (x, HEIGHT_M, z) at z = HEIGHT_M / ry
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(ry > 1e-3, HEIGHT_M / ry, np.nan)
    gx, gz = rx * z, z + travelled_m
    img = cv2.remap(ROAD, np.nan_to_num(gx * 60.0 % 1024).astype(np.float32),
                    np.nan_to_num(gz * 6.5 % 1024).astype(np.float32), cv2.INTER_LINEAR)
    img = np.where(np.isfinite(z), img, 160.0)
    # the object: its plane at depth_m, texture fixed on it
    ox, oy = rx * depth_m - lateral_m, ry * depth_m
    if swing_m:
        left_leg = (oy > HEIGHT_M - 0.5 * height_m) & (ox + swing_m < 0.0) \
            & (ox > -0.5 * width_m - swing_m)
        ox = np.where(left_leg, ox + swing_m, ox)
    inside = (np.abs(ox) <= 0.5 * width_m) & (oy <= HEIGHT_M) & (oy >= HEIGHT_M - height_m)
    if legs:
        gap = (np.abs(ox) < 0.12) & (oy > HEIGHT_M - 0.5 * height_m)
        inside &= ~gap
    body = cv2.remap(BODY, ((ox + 1.0) * 60.0 % 1024).astype(np.float32),
                     ((oy + 1.0) * 60.0 % 1024).astype(np.float32), cv2.INTER_LINEAR)
    img = np.where(inside, body, img)
    return np.clip(img, 0, 255).astype(np.uint8)


def feet_row(depth_m: float) -> float:
    return CAM.cy + CAM.fy * HEIGHT_M / depth_m


def pedestrian(depth_m: float = 12.0, lateral_m: float = 1.2, legs: bool = False,
               swing_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Previous and current frame of a pedestrian on a collision course: it keeps its bearing
    while the camera drives TRAVEL_M nearer (and its left leg swings ``swing_m`` ahead)."""
    prev_depth = depth_m + TRAVEL_M
    prev = render(prev_depth, lateral_m * prev_depth / depth_m, 0.0, legs=legs)
    cur = render(depth_m, lateral_m, TRAVEL_M, legs=legs, swing_m=swing_m)
    return prev, cur


def hips_box(depth_m: float, lateral_m: float) -> tuple[float, float, float, float]:
    """The cluster's box: the object's upper body, its bottom 0.6 m above the road (the
    contact there reads 1.9 times too far)."""
    uc = CAM.cx + CAM.fx * lateral_m / depth_m
    half = CAM.fx * 0.2 / depth_m
    top = CAM.cy + CAM.fy * (HEIGHT_M - 1.6) / depth_m
    return (uc - half, top, uc + half, CAM.cy + CAM.fy * (HEIGHT_M - 0.6) / depth_m)


def found(prev: np.ndarray, cur: np.ndarray, box: tuple[float, float, float, float],
          object_flow: np.ndarray, cfg: Config) -> Foot:
    p = foot_probe(box, CAM, POSE, MOTION, halo_px=0.5 * cfg.flow.window_px)
    assert p is not None
    f = measure_points(prev, cur, {0: p.points}, np.zeros(3), CAM, cfg.flow)[0]
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = foot(p, f.flow, f.valid, object_flow, at, sigma_px=0.5, tensor=f.tensor)
    assert out is not None
    return out


def expansion_flow(at: np.ndarray, depth_m: float) -> np.ndarray:
    """The flow of a point of an object keeping its bearing: it only grows about the centre."""
    y = (at[1] - CAM.cy) / CAM.fy * depth_m
    return np.array([0.0, CAM.fy * y * (1.0 / depth_m - 1.0 / (depth_m + TRAVEL_M))])


def test_the_road_flow_is_the_flow_of_a_rendered_road_point(default_config: Config) -> None:
    prev, cur = render(50.0, 30.0, 0.0), render(50.0, 30.0, TRAVEL_M)   # object out of sight
    pts = np.array([[200.0, 330.0], [320.0, 360.0], [450.0, 300.0]])
    measured = measure_points(prev, cur, {0: pts}, np.zeros(3), CAM, default_config.flow)[0]
    assert measured.valid.all()
    predicted = road_flow(CAM, pts, POSE, MOTION)
    error = np.linalg.norm(measured.flow - predicted, axis=1)
    assert np.all(error < 0.15 * np.linalg.norm(predicted, axis=1) + 0.2), error


@pytest.mark.parametrize("depth_m", [6.0, 9.0, 12.0])
def test_the_feet_are_found_below_a_cluster_on_the_hips(default_config: Config,
                                                        depth_m: float) -> None:
    prev, cur = pedestrian(depth_m)
    box = hips_box(depth_m, 1.2)
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    truth = feet_row(depth_m)
    assert out.rows > 0
    # within a few pixels of the feet: the contact's range within 10 %
    assert abs(out.bottom - truth) <= 0.1 * (truth - CAM.cy) + 1.0, (out, truth)


def test_too_far_to_tell_the_object_from_the_road_the_box_stays(default_config: Config) -> None:
    """At 30 m its flow and the road's at its feet differ by less than two flow std: nothing
    is said, and nothing wrong."""
    depth_m = 30.0
    prev, cur = pedestrian(depth_m, lateral_m=2.0)
    box = hips_box(depth_m, 2.0)
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    assert out.bottom <= feet_row(depth_m) + 1.0


def test_between_the_legs_the_road_does_not_end_the_object(default_config: Config) -> None:
    depth_m = 10.0
    prev, cur = pedestrian(depth_m, legs=True)
    box = hips_box(depth_m, 1.2)
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    truth = feet_row(depth_m)
    assert abs(out.bottom - truth) <= 0.1 * (truth - CAM.cy) + 1.0, (out, truth)


@pytest.mark.parametrize("depth_m", [18.0, 22.0])
def test_a_swinging_leg_reaches_down_to_the_feet(default_config: Config, depth_m: float) -> None:
    """18-22 m ahead the body's own flow at its feet lies within two flow std of the road's, so
    the body says nothing there; the leg that swings ahead of it (0.06 m per frame: walking at
    1.4 m/s, 25 frames/s) flows far from both the road's and the body's, and the object reaches
    down near the feet. The contact read from the cluster's own bottom is 86 % too far; from the
    foot, less than 15 %: a limb swinging says the object's lowest part on the road stands
    still and flows like it, so the last row is not moved half a window up (it was: 23 %)."""
    prev, cur = pedestrian(depth_m, legs=True, swing_m=0.06)
    box = hips_box(depth_m, 1.2)
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    assert out.rows > 0
    assert out.bottom <= feet_row(depth_m) + 1.0
    assert CAM.fy * HEIGHT_M / (out.bottom - CAM.cy) <= 1.15 * depth_m, (out, feet_row(depth_m))


def test_a_cluster_at_the_feet_stays_where_it_is(default_config: Config) -> None:
    depth_m = 12.0
    prev, cur = pedestrian(depth_m)
    u0, v0, u1, _ = hips_box(depth_m, 1.2)
    box = (u0, v0, u1, feet_row(depth_m))
    at = np.array([0.5 * (u0 + u1), 0.5 * (v0 + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    assert out.rows == 0 and out.bottom == box[3]


def test_an_object_moving_like_the_road_says_nothing(default_config: Config) -> None:
    """A static object (its flow that of the road at its feet) cannot be told from the road
    below it: the box stays as it is."""
    depth_m = 12.0
    prev = render(depth_m + TRAVEL_M, 1.2, 0.0)
    cur = render(depth_m, 1.2, TRAVEL_M)
    box = hips_box(depth_m, 1.2)
    at = np.array([0.5 * (box[0] + box[2]), feet_row(depth_m)])
    out = found(prev, cur, box, road_flow(CAM, at[None, :], POSE, MOTION)[0], default_config)
    assert out.rows == 0


def test_nothing_measured_keeps_the_box(default_config: Config) -> None:
    box = hips_box(12.0, 1.2)
    p = foot_probe(box, CAM, POSE, MOTION)
    assert p is not None
    n = len(p.points)
    out = foot(p, np.zeros((n, 2)), np.zeros(n, dtype=bool), np.zeros(2), np.zeros(2), 0.5)
    assert out == Foot(bottom=box[3], rows=0, at_edge=False)
    assert foot(p, None, None, np.zeros(2), np.zeros(2), 0.5) is None


def test_no_probe_above_the_horizon_or_without_a_box() -> None:
    assert foot_probe((300.0, 150.0, 320.0, 230.0), CAM, POSE, MOTION) is None
    assert foot_probe((300.0, 300.0, 300.0, 330.0), CAM, POSE, MOTION) is None


def test_feet_below_the_image_are_out_of_sight(default_config: Config) -> None:
    """A pedestrian 3 m ahead: its feet are below the image's bottom, the flow follows it to
    the last row, and the foot says so (no contact can be taken)."""
    depth_m = 3.0
    prev, cur = pedestrian(depth_m, lateral_m=0.3)
    box = hips_box(depth_m, 0.3)
    at = np.array([0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])])
    out = found(prev, cur, box, expansion_flow(at, depth_m), default_config)
    assert feet_row(depth_m) > CAM.height
    assert out.at_edge


def test_the_contact_is_taken_at_the_feet() -> None:
    """The ground contact moves from the hips' row to the feet's: the range from 22 m (what
    the hips' row says) to the 12 m the object stands at."""
    depth_m = 12.0
    box = hips_box(depth_m, 1.2)
    c = Cluster(bbox=box, region_bbox=box, n=10, foot_v=box[3], mean_flow=(0.0, 0.0),
                mean_probability=0.8, positions=np.zeros((0, 2)), flows=np.zeros((0, 2)),
                s=np.zeros(0), weights=np.zeros(0))
    still = np.zeros(3)
    f = FrameContext(t=0.0, dt=0.04, pose=POSE, sensors=SensorSample(0.0, 10.0, 0.0),
                     ego=EgoMotion(still, still, None, still, still, None, 0, True),
                     odo=(0.0, 0.0, 0.0), camera=CAM, mount=load_config().mount, window_px=9,
                     flow_std_px=0.5)
    model = GroundModel()
    hips = ground_contact(CAM, (0.5 * (box[0] + box[2]), box[3]), POSE, model)
    assert hips is not None
    low = lowered_contact(c, f, model, hips, feet_row(depth_m))
    assert low is not None
    assert hips.z[0] - POSE.position[0] == pytest.approx(depth_m * 1.3 / 0.7, rel=0.02)
    assert low.z[0] - POSE.position[0] == pytest.approx(depth_m, rel=0.02)
    # never raised: a foot above the contact's row keeps the contact
    assert lowered_contact(c, f, model, hips, box[3] - 5.0) is hips


def test_the_reported_box_reaches_down_to_the_foot() -> None:
    from appliance.decision.cues.peaks import shown
    from appliance.decision.object_extent import Outline
    from appliance.decision.tracking import ImageModel, TrackerState, track_step

    box = hips_box(12.0, 1.2)
    c = Cluster(bbox=box, region_bbox=box, n=10, foot_v=box[3], mean_flow=(0.0, 0.0),
                mean_probability=0.8, positions=np.zeros((0, 2)), flows=np.zeros((0, 2)),
                s=np.zeros(0), weights=np.zeros(0))
    cfg = load_config().tracking
    tr = track_step(TrackerState(), (c,), cfg, ImageModel.from_config(cfg)).tracks[0]
    feet = feet_row(12.0)
    out = shown(tr, {"foot": Foot(bottom=feet, rows=5)})
    assert out.bbox[3] == pytest.approx(feet) and out.bbox[1] == pytest.approx(tr.bbox[1])
    up = shown(tr, {"foot": Foot(bottom=feet, rows=5),
                    "outline": Outline(top=150.0, positions=np.zeros((0, 2)),
                                       flows=np.zeros((0, 2)))})
    assert up.bbox[1] == pytest.approx(150.0) and up.bbox[3] == pytest.approx(feet)
    # a foot that found nothing below the box leaves it as it is
    assert shown(tr, {"foot": Foot(bottom=box[3], rows=0)}) is tr
