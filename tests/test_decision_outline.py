"""The reported outline of a track (decision/object_extent.py) on rendered image pairs.

A textured upright object (120 px tall) moves over a textured background that moves
differently; the track's box is only the strip at its feet, as the particle filter
gives it for a pedestrian. The flow vision measures up the columns (vision/probes.py) finds
where the object ends.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from appliance.config import Config, load_config
from appliance.decision.cues import TrackCues
from appliance.decision.cues.outline import closing_step, outline_depth
from appliance.decision.frame import FrameContext
from appliance.decision.ground_state import CameraPose, GroundTrack
from appliance.decision.object_extent import Outline, extended, outline, outline_probe
from appliance.decision.scale_ttc import measure_expansion
from appliance.decision.tracking import ImageTrack
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import FloatArray, PinholeCamera, matrix_to_euler
from appliance.vision.probes import measure_points

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
OBJ = (300, 180, 340, 300)          # u0, v0, u1, v1 of the object in the current frame
FEET = (302.0, 290.0, 338.0, 300.0)  # the track's box: its lowest 10 px
DEPTH_M = 10.0                      # 2 m at 10 m: 140 px, above the object's 120


def texture(seed: int, shape: tuple[int, int]) -> np.ndarray:
    noise = np.random.default_rng(seed).uniform(0, 255, shape).astype(np.float32)
    return np.clip(cv2.GaussianBlur(noise, (0, 0), 1.5) * 2.0 - 128.0, 0, 255).astype(np.uint8)


def shifted(img: np.ndarray, du: float, dv: float, scale: float = 1.0,
            centre: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    cu, cv = centre
    A = np.array([[scale, 0.0, (1 - scale) * cu + du], [0.0, scale, (1 - scale) * cv + dv]])
    return cv2.warpAffine(img, A, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REFLECT)


def pair(obj_flow: tuple[float, float], bg_flow: tuple[float, float], scale: float = 1.0,
         flat_object: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Previous and current frame: background moved by ``bg_flow``, the object by ``obj_flow``
    and magnified by ``scale`` about its feet (it comes nearer)."""
    bg = texture(1, (CAM.height, CAM.width))
    obj = np.full((CAM.height, CAM.width), 90, np.uint8) if flat_object else texture(2, (CAM.height, CAM.width))
    u0, v0, u1, v1 = OBJ
    feet = (0.5 * (u0 + u1), float(v1))
    mask = np.zeros((CAM.height, CAM.width), np.uint8)
    mask[v0:v1, u0:u1] = 255
    # previous frame: the object's region where it was (inverse of this frame's motion)
    inv = 1.0 / scale
    prev_mask = shifted(mask, -obj_flow[0], -obj_flow[1], inv, feet) > 127
    prev_obj = shifted(obj, -obj_flow[0], -obj_flow[1], inv, feet)
    prev = np.where(prev_mask, prev_obj, bg)
    cur = np.where(mask > 127, obj, shifted(bg, *bg_flow))
    return prev, cur


def outline_of(prev: np.ndarray, cur: np.ndarray, box: tuple[float, float, float, float],
               depth: float, cfg: Config, expansion: float = 0.0, max_height_m: float = 2.0,
               rotation: FloatArray | None = None) -> Outline:
    """The outline of the object whose lower part is ``box``: its probe, the flow vision
    measures there (the camera having rotated by ``rotation``), and what that says."""
    R = np.eye(3) if rotation is None else rotation
    p = outline_probe(box, depth, CAM, max_height_m)
    if p is None:
        return Outline(top=box[1], positions=np.zeros((0, 2)), flows=np.zeros((0, 2)))
    f = measure_points(prev, cur, {0: p.points}, matrix_to_euler(R), CAM, cfg.flow)[0]
    out = outline(p, f.flow, f.valid, CAM, R, expansion, tolerance=0.3)
    assert out is not None
    return out


def frame(speed: float, pose: CameraPose, dt: float = 1.0 / 30.0) -> FrameContext:
    still = np.zeros(3)
    ego = EgoMotion(still, still, None, still, still, None, 0, True)
    return FrameContext(t=0.0, dt=dt, pose=pose, sensors=SensorSample(0.0, speed, 0.0), ego=ego,
                        odo=(0.0, 0.0, 0.0), camera=CAM, mount=load_config().mount, window_px=9,
                        flow_std_px=0.5)


def test_the_outline_reaches_the_top_of_the_object(default_config: Config) -> None:
    prev, cur = pair((1.0, 0.0), (3.0, 0.5))
    top = outline_of(prev, cur, FEET, DEPTH_M, default_config).top
    assert top == pytest.approx(OBJ[1], abs=8.0)


def test_without_the_expansion_a_nearing_object_is_cut_short(default_config: Config) -> None:
    """Magnified 2 % per frame about its feet, the object's top moves 2.4 px more upward
    than its feet: with that expansion given the whole object is found, without it not."""
    prev, cur = pair((1.0, 0.0), (3.0, 0.5), scale=1.02)
    right = outline_of(prev, cur, FEET, DEPTH_M, default_config, expansion=0.02).top
    wrong = outline_of(prev, cur, FEET, DEPTH_M, default_config, expansion=0.0).top
    assert right == pytest.approx(OBJ[1], abs=8.0)
    assert wrong > OBJ[1] + 30.0


def test_the_height_cap_holds_where_the_background_moves_like_the_object(
        default_config: Config) -> None:
    """Nothing distinguishes object and background: the outline stops at 2 m above the feet."""
    prev, cur = pair((1.0, 0.0), (1.0, 0.0))
    top = outline_of(prev, cur, FEET, DEPTH_M, default_config, max_height_m=1.0).top
    assert top == pytest.approx(FEET[3] - 1.0 * CAM.fy / DEPTH_M, abs=0.01)


def test_nothing_to_measure_keeps_the_box(default_config: Config) -> None:
    """A flat object (LK cannot measure its flow in the box), black frames and degenerate inputs
    (negative or NaN depth, an empty or NaN box) keep the box top."""
    prev, cur = pair((1.0, 0.0), (3.0, 0.5), flat_object=True)
    assert outline_of(prev, cur, FEET, DEPTH_M, default_config).top == FEET[1]
    assert outline_of(prev, cur, FEET, -1.0, default_config).top == FEET[1]
    assert outline_of(prev, cur, (300.0, 300.0, 300.0, 310.0), DEPTH_M, default_config).top == 300.0
    assert outline_of(prev, cur, FEET, float("nan"), default_config).top == FEET[1]
    nan_box = (float("nan"), 290.0, 338.0, 300.0)
    assert outline_of(prev, cur, nan_box, DEPTH_M, default_config).top == 290.0
    black = np.zeros_like(prev)
    assert outline_of(black, black, FEET, DEPTH_M, default_config).top == FEET[1]


def test_extended_keeps_bottom_and_width() -> None:
    x = np.zeros((2, 3))
    x[0, 0], x[1, 0] = 320.0, 295.0
    tr = ImageTrack(uid=1, id=1, x=x, P=np.zeros((2, 3, 3)), size=(36.0, 10.0), age=5, misses=0,
                    cluster=None, probability=0.7)
    out = extended(tr, 180.0)
    assert out.bbox == pytest.approx((302.0, 180.0, 338.0, 300.0))
    assert extended(tr, 295.0) is tr      # below the box top: unchanged


def test_the_outline_flows_measure_the_expansion(default_config: Config) -> None:
    """The points the outline rests on carry the object's scale change (2 %/frame here) for
    the scale cue, better than the 10 px strip at the feet."""
    prev, cur = pair((1.0, 0.0), (3.0, 0.5), scale=1.02)
    shape = outline_of(prev, cur, FEET, DEPTH_M, default_config, expansion=0.02)
    assert len(shape.positions) >= 40 and shape.positions[:, 1].min() < OBJ[1] + 10
    m = measure_expansion(shape.positions, shape.flows, np.ones(len(shape.positions)), None, CAM)
    assert m is not None and m.kappa == pytest.approx(0.02, abs=0.002)
    strip = shape.positions[:, 1] > FEET[1]
    feet = measure_expansion(shape.positions[strip], shape.flows[strip], np.ones(int(strip.sum())),
                             None, CAM)
    assert feet is None or abs(feet.kappa - 0.02) > 2 * abs(m.kappa - 0.02)


def test_during_a_pan_the_outline_compares_the_flows_without_the_rotation(
        default_config: Config) -> None:
    """A PTU pan adds ~14 px to every flow: the object moves 15 px, the background 17 px.
    From the point itself LK loses the probes and the outline stays at the box; with the
    pan's rotation given, LK starts where the pan moved them and the flows are compared
    without it: the whole object is found."""
    from appliance.vision.geometry import rot_y, rotate_pixels

    pan = rot_y(np.arctan(14.0 / CAM.fx))
    centre = np.array([[320.0, 240.0]])
    assert rotate_pixels(CAM, centre, pan)[0, 0] - 320.0 == pytest.approx(14.0, abs=0.1)
    prev, cur = pair((15.0, 0.0), (17.0, 0.5))
    blind = outline_of(prev, cur, FEET, DEPTH_M, default_config).top
    seen = outline_of(prev, cur, FEET, DEPTH_M, default_config, rotation=pan).top
    assert seen == pytest.approx(OBJ[1], abs=8.0)
    assert abs(blind - OBJ[1]) > 20.0


def test_a_track_beyond_the_3d_range_is_outlined_at_its_roads_depth(default_config: Config) -> None:
    """A cyclist at 80 m is further than cue.ground.max_range_m: no ground contact, no 3-D state.
    Its outline is still measured at the road's depth under its cluster (~80 m), so its
    reported box is the whole cyclist, not the strip of particles at its wheels; with a 3-D
    state that state's depth counts, and above the horizon there is none."""
    from appliance.decision.clustering import Cluster

    pose = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
    f = frame(10.0, pose)
    far = 80.0
    foot_v = CAM.cy + CAM.fy * 1.3 / far + 0.5     # the road 80 m ahead (foot_v is exclusive)
    assert far > default_config.cue.ground.max_range_m

    def track(foot: float) -> ImageTrack:
        c = Cluster(bbox=(330.0, foot - 3.0, 340.0, foot), region_bbox=(330.0, foot - 3.0, 340.0, foot),
                    n=3, foot_v=foot, mean_flow=(0.0, 0.0), mean_probability=0.8,
                    positions=np.zeros((3, 2)), flows=np.zeros((3, 2)), s=np.ones(3),
                    weights=np.ones(3))
        x = np.array([[335.0, 0.0, 0.0], [foot - 1.5, 0.0, 0.0]])
        return ImageTrack(uid=1, id=1, x=x, P=np.ones((2, 3, 3)), size=(10.0, 3.0), age=9,
                          misses=0, cluster=c, probability=0.8)

    depth = outline_depth(track(foot_v), TrackCues(), f)
    assert depth == pytest.approx(far, rel=0.01)
    g = GroundTrack(x=np.array([1.9 + 30.0, 0.0, 0.0, 0.0]), P=np.eye(4), t_update=0.0, updates=5)
    assert outline_depth(track(foot_v), TrackCues(ground=g), f) == pytest.approx(30.0)
    assert outline_depth(track(CAM.cy - 20.0), TrackCues(), f) is None
    no_cluster = replace(track(foot_v), cluster=None)
    assert outline_depth(no_cluster, None, f) is None


def test_the_expansion_is_the_closing_speed_not_the_ego_speed(default_config: Config) -> None:
    """The outline expects the object to grow by what the camera closes on it: a lead car at
    the ego's speed does not grow, and with the ego's travel alone (13.9 m/s, 10 m ahead: 4.6 %
    a frame) its top rows look like another object's; a pedestrian crossing does grow by it."""
    dt = 1.0 / 30.0
    ahead = frame(13.9, CameraPose((1.9, 0.0, 1.3), pitch=0.0, pan=0.0, tilt=0.0))

    def cues(vx: float, vy: float) -> TrackCues:
        return TrackCues(ground=GroundTrack(x=np.array([11.9, 0.0, vx, vy]), P=np.eye(4),
                                            t_update=0.0, updates=10))

    assert closing_step(None, ahead) == pytest.approx(13.9 * dt)
    assert closing_step(cues(13.9, 0.0), ahead) == pytest.approx(0.0, abs=1e-12)
    assert closing_step(cues(0.0, 1.4), ahead) == pytest.approx(13.9 * dt)
    # panned 0.3 rad left: the car ahead at the ego's speed still does not close
    panned = frame(13.9, CameraPose((1.9, 0.0, 1.3), pitch=0.0, pan=0.3, tilt=0.0))
    assert closing_step(cues(13.9, 0.0), panned) == pytest.approx(0.0, abs=1e-12)
    # a car crossing to the left at 8 m/s: what it drives away along the axis is taken off; a
    # pedestrian (below 5 m/s) counts as static (the ego's travel), its axial velocity being
    # the least certain part of its state
    assert closing_step(cues(0.0, 8.0), panned) == pytest.approx(
        (13.9 * np.cos(0.3) - 8.0 * np.sin(0.3)) * dt, rel=1e-9)
    assert closing_step(cues(0.0, 1.4), panned) == pytest.approx(13.9 * dt)

    prev, cur = pair((1.0, 0.0), (3.0, 0.5))          # the lead car: no growth of its own
    lead = closing_step(cues(13.9, 0.0), ahead) / DEPTH_M
    static = closing_step(None, ahead) / DEPTH_M
    assert outline_of(prev, cur, FEET, DEPTH_M, default_config, lead).top == \
        pytest.approx(OBJ[1], abs=8.0)
    assert outline_of(prev, cur, FEET, DEPTH_M, default_config, static).top > OBJ[1] + 30.0
