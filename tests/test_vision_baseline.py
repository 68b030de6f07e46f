"""The flow-length cue over a longer baseline: composed motions, the baseline's span, and a
mover on a collision course near the epipole on rendered images."""

from __future__ import annotations

import numpy as np
import pytest
from test_vision_perception import drive, on_box
from test_vision_scene import Box, Scene

from appliance.config import Config
from appliance.vision import baseline
from appliance.vision import geometry as g
from appliance.vision.baseline import PastFrame, compose, search_start, start_frame
from appliance.vision.likelihood import CameraMotion

IMAGE = np.zeros((4, 4), dtype=np.uint8)


def test_compose_is_the_frames_motions_applied_in_turn() -> None:
    rng = np.random.default_rng(3)
    motions = [(g.euler_to_matrix(rng.normal(0.0, 0.01, 3)), rng.normal(0.0, 0.4, 3))
               for _ in range(4)]
    past = tuple(PastFrame(IMAGE, 0.1 * k, m) for k, m in enumerate(motions))
    X = rng.normal(0.0, 10.0, (20, 3))
    Y = X.copy()
    for R, t in motions:
        Y = Y @ R.T + t
    composed = compose(past)
    assert composed is not None
    R, t = composed
    np.testing.assert_allclose(X @ R.T + t, Y, atol=1e-9)
    # one unknown motion (no metric translation) and there is no composed one
    assert compose(past[:2] + (PastFrame(IMAGE, 0.3, None),) + past[3:]) is None


@pytest.mark.parametrize(("fps", "frames_back"), [(25.0, 4), (30.0, 5), (15.0, 2), (10.0, None)])
def test_the_baseline_spans_the_most_frames_within_its_time(fps: float, frames_back: int | None
                                                         ) -> None:
    still = (np.eye(3), np.zeros(3))
    past = tuple(PastFrame(IMAGE, k / fps, still) for k in range(8))   # the previous frame last
    now = 8 / fps
    i = start_frame(past, now)
    if frames_back is None:   # two frames back is longer than the baseline already
        assert i is None
        return
    assert i is not None
    assert len(past) - i == frames_back
    assert now - past[i].t <= baseline.BASELINE_S
    # the previous frame alone is the short baseline: no longer one
    assert start_frame(past[-1:], now) is None


# a pedestrian-sized box 30 m ahead of the camera and 2.8 m right of its path, walking into
# the path where the car's front (2 m ahead of the camera) meets it at 10 m/s: 65 px right of
# the epipole, it moves 0.05 px per frame, where the road beside its feet flows 0.7 px
AHEAD_M, RIGHT_M, FRONT_M = 30.0, -2.8, 2.0
COLLISION = Box(x_m=1.9 + AHEAD_M, y_m=RIGHT_M, width_m=0.6, height_m=1.8,
                vy_m_s=-RIGHT_M * 10.0 / (AHEAD_M - FRONT_M))


def box_weights(cfg: Config, frames: int) -> tuple[float, float]:
    """Mean particle weight on the box, and share of the valid particles farther from it than
    a Lucas-Kanade window (whose windows do not reach it) weighing more than 0.5, over the
    last four frames of a drive."""
    on, off = [], []
    w = cfg.flow.window_px
    scene = Scene(boxes=(COLLISION,))
    for _, _, particles, box in drive(cfg, frames, scene, box_of=COLLISION)[-4:]:
        inside = on_box(particles, box) & particles.valid
        halo = (box[0] - w, box[1] - w, box[2] + w, box[3] + w)
        apart = ~on_box(particles, halo) & particles.valid
        on.extend(particles.weights[inside])
        off.extend(particles.weights[apart] > 0.5)
    return float(np.mean(on)), float(np.mean(off))


def test_a_mover_on_a_collision_course_near_the_epipole_stands_out_over_the_longer_baseline(
        default_config: Config, monkeypatch: pytest.MonkeyPatch) -> None:
    longer, longer_false = box_weights(default_config, 16)
    monkeypatch.setattr(baseline, "BASELINE_S", 0.0)   # every pixel over one frame
    short, short_false = box_weights(default_config, 16)
    assert longer > 0.8
    assert longer > short + 0.2
    # the road and the wall behind it, with the body pitching on a bump, stay static
    assert longer_false < 0.02
    assert short_false < 0.02


def test_the_search_starts_where_a_static_point_was_not_where_the_rotation_alone_puts_it() -> None:
    camera = g.PinholeCamera(640, 480, 600.0, 600.0, 319.5, 239.5)
    rng = np.random.default_rng(5)
    # static points 8-40 m ahead, off the epipole; the camera drives 0.4 m per frame, yawing
    X = np.column_stack([rng.uniform(-6, 6, 50), rng.uniform(-1, 1.5, 50), rng.uniform(8, 40, 50)])
    step = (g.euler_to_matrix(np.array([0.0, 0.002, 0.0])), np.array([0.0, 0.0, -0.4]))
    frames = [X]
    for _ in range(4):
        frames.append(frames[-1] @ step[0].T + step[1])
    then, prev, now = (camera.project(P) for P in (frames[0], frames[-2], frames[-1]))
    past = tuple(PastFrame(IMAGE, 0.04 * k, step) for k in range(4))
    composed = compose(past)
    assert composed is not None
    R, t = composed
    short = CameraMotion(R=step[0], t_dir=step[1] / 0.4, t_m=step[1], standstill=False, K=camera.K)
    start = search_start(camera, camera.undistort(now), camera.undistort(prev), short, R,
                         float(np.linalg.norm(t)) / 0.4)
    rotation_only = g.lk_start(camera, now, R.T)
    err = np.hypot(*(start - then).T)
    err_rot = np.hypot(*(rotation_only - then).T)
    assert np.median(err_rot) > 1.0
    assert np.median(err) < 0.2 * np.median(err_rot)
