"""perceive(): the vision core per frame on rendered images, bad input, determinism."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from test_vision_scene import CAMERA, Box, Scene, box_bbox, pose, render

from appliance.config import Config
from appliance.errors import UsageError
from appliance.messages import EgoMotion, Frame, ParticleSet, ProbabilityMap, SensorSample
from appliance.pipeline import init_state, step
from appliance.vision import geometry as g
from appliance.vision.perception import (
    FrameFormatError,
    VisionState,
    init_vision_state,
    perceive,
    static_pool,
)

FPS = 30.0
SPEED = 10.0


def bump_pitch(t: float) -> float:
    """Body pitch (rad) of a road bump that CAN does not see: 0.25 deg at 1.5 Hz."""
    return 0.0044 * math.sin(2.0 * math.pi * 1.5 * t)


CROSSING = Box(x_m=22.0, y_m=-3.5, width_m=0.6, height_m=1.8, vy_m_s=1.5)


def drive(cfg: Config, frames: int, scene: Scene, speed: float = SPEED, seed: int = 0,
          can_valid: bool = True, box_of: Box = CROSSING
          ) -> list[tuple[np.ndarray, EgoMotion, ParticleSet, tuple[float, ...]]]:
    """Run perceive over a rendered drive; per frame: pose, ego motion, particles, the box of
    ``box_of`` (the crossing object by default)."""
    state = init_vision_state(cfg, CAMERA, seed)
    out = []
    for k in range(frames):
        t = k / FPS
        T = pose(speed * t, pitch_rad=bump_pitch(t))
        frame = Frame(k, t, render(CAMERA, T, scene, t))
        sensors = SensorSample(t, speed, 0.0, can_valid=can_valid)
        state, ego, particles = perceive(state, frame, sensors, None, cfg, CAMERA)
        box = box_bbox(CAMERA, T, box_of.at(t)) if scene.boxes else (0.0, 0.0, 0.0, 0.0)
        out.append((T, ego, particles, box))
    return out


@pytest.fixture(scope="module")
def driven(default_config: Config) -> list[tuple[np.ndarray, EgoMotion, ParticleSet, tuple[float, ...]]]:
    return drive(default_config, 9, Scene(boxes=(CROSSING,)))


def test_first_frame_gives_the_prior_only_and_no_valid_particles(driven: list) -> None:  # type: ignore[type-arg]
    _, ego, particles, _ = driven[0]
    assert not ego.confident and ego.inliers == 0
    assert particles.positions.shape == (500, 2)
    assert not particles.valid.any() and not particles.weights.any()


def test_refinement_on_images_halves_the_prior_rotation_error(driven: list) -> None:  # type: ignore[type-arg]
    errors, prior_errors, heading = [], [], []
    for (T0, _, _, _), (T1, ego, _, _) in itertools.pairwise(driven):
        R, t = g.relative_motion(T0, T1)
        errors.append(g.rotation_angle(g.euler_to_matrix(ego.rotation).T @ R))
        prior_errors.append(g.rotation_angle(g.euler_to_matrix(ego.prior_rotation).T @ R))
        heading.append(math.acos(min(1.0, float(ego.translation_dir @ (t / np.linalg.norm(t))))))
        assert ego.confident and ego.inliers >= 100
    assert math.degrees(np.median(errors)) < 0.05
    assert np.median(errors) < 0.5 * np.median(prior_errors)
    assert math.degrees(np.median(heading)) < 1.0


def on_box(particles: ParticleSet, box: tuple[float, ...]) -> np.ndarray:
    u0, v0, u1, v1 = box
    pos = particles.positions
    return (pos[:, 0] >= u0 - 3) & (pos[:, 0] <= u1 + 3) & (pos[:, 1] >= v0 - 3) & (pos[:, 1] <= v1 + 3)


def test_particles_gather_on_a_crossing_object(driven: list) -> None:  # type: ignore[type-arg]
    _, _, particles, box = driven[-1]
    inside = on_box(particles, box)
    high = particles.weights > 0.5
    assert high.sum() >= 5
    assert inside[high].mean() > 0.9
    assert np.all((particles.weights >= 0.0) & (particles.weights <= 1.0))
    # the filter gathers measurements on it: more particles on the box than a few frames ago
    early = on_box(driven[2][2], driven[2][3]).sum()
    assert inside.sum() >= 2 * max(early, 1)


def test_standstill_gives_no_detections(default_config: Config) -> None:
    for _, ego, particles, _ in drive(default_config, 4, Scene(), speed=0.0):
        assert ego.standstill
        assert not np.any(particles.weights > 0.5)


def test_covered_camera_gives_no_detections_and_keeps_the_prior(default_config: Config) -> None:
    state = init_vision_state(default_config, CAMERA, 0)
    black = np.zeros((480, 640), np.uint8)
    for k in range(3):
        state, ego, particles = perceive(state, Frame(k, k / FPS, black), SensorSample(k / FPS, SPEED, 0.0),
                                         None, default_config, CAMERA)
        assert not ego.confident and ego.inliers == 0
        assert not particles.valid.any() and not np.any(particles.weights > 0.0)
        np.testing.assert_array_equal(ego.rotation, ego.prior_rotation)


def test_missing_can_flags_low_confidence_without_raising(default_config: Config) -> None:
    for _, ego, particles, _ in drive(default_config, 3, Scene(), can_valid=False)[1:]:
        assert not ego.confident
        assert np.all(np.isfinite(ego.rotation)) and np.all(np.isfinite(particles.weights))


def test_a_frame_of_another_size_or_type_is_a_clear_error_and_loses_nothing(
        default_config: Config) -> None:
    cfg = default_config
    state = init_state(cfg, CAMERA)
    img = render(CAMERA, pose(0.0), Scene())
    state, _, _ = step(state, Frame(0, 0.0, img), SensorSample(0.0, SPEED, 0.0), cfg, CAMERA)
    bad = {
        "frame 1: image is 320x240, the camera is configured for 640x480 gray": img[::2, ::2].copy(),
        "frame 1: image is 640x480x3, the camera is configured for 640x480 gray":
            np.dstack([img, img, img]),
        "frame 1: pixels are float32, expected 8-bit": img.astype(np.float32),
    }
    for message, image in bad.items():
        with pytest.raises(FrameFormatError, match=message) as info:
            step(state, Frame(1, 1 / FPS, image), SensorSample(1 / FPS, SPEED, 0.0), cfg, CAMERA)
        assert isinstance(info.value, UsageError)   # the command line: one line, exit status 2
    # the state is untouched: the next good frame carries on
    _, out, _ = step(state, Frame(2, 2 / FPS, render(CAMERA, pose(2 * SPEED / FPS), Scene())),
                     SensorSample(2 / FPS, SPEED, 0.0), cfg, CAMERA)
    assert out.ego.confident


def test_same_inputs_give_identical_outputs(default_config: Config) -> None:
    img0 = render(CAMERA, pose(0.0), Scene(boxes=(CROSSING,)), 0.0)
    img1 = render(CAMERA, pose(SPEED / FPS), Scene(boxes=(CROSSING,)), 1 / FPS)

    def run() -> tuple[VisionState, EgoMotion, ParticleSet]:
        s = init_vision_state(default_config, CAMERA, 7)
        s, _, _ = perceive(s, Frame(0, 0.0, img0), SensorSample(0.0, SPEED, 0.0), None, default_config, CAMERA)
        return perceive(s, Frame(1, 1 / FPS, img1), SensorSample(1 / FPS, SPEED, 0.0), None,
                        default_config, CAMERA)

    (s1, e1, p1), (s2, e2, p2) = run(), run()
    np.testing.assert_array_equal(e1.rotation, e2.rotation)
    np.testing.assert_array_equal(p1.weights, p2.weights)
    np.testing.assert_array_equal(s1.particles, s2.particles)
    # and calling perceive twice on the same state does not consume randomness
    s = init_vision_state(default_config, CAMERA, 7)
    s, _, _ = perceive(s, Frame(0, 0.0, img0), SensorSample(0.0, SPEED, 0.0), None, default_config, CAMERA)
    a = perceive(s, Frame(1, 1 / FPS, img1), SensorSample(1 / FPS, SPEED, 0.0), None, default_config, CAMERA)
    b = perceive(s, Frame(1, 1 / FPS, img1), SensorSample(1 / FPS, SPEED, 0.0), None, default_config, CAMERA)
    np.testing.assert_array_equal(a[0].particles, b[0].particles)


def test_static_pool_avoids_regions_the_decision_marked_as_moving(default_config: Config) -> None:
    img = render(CAMERA, pose(0.0), Scene())
    p = np.zeros((120, 160), np.float32)
    p[:, :40] = 1.0                        # left quarter of the image: moving, p(x) = 1
    pos, keep = static_pool(img, ProbabilityMap(p, 4), default_config, np.random.default_rng(0))
    assert len(pos) == default_config.refinement.static_points
    assert np.mean(pos[:, 0] < 160) < 0.02
    assert np.all(keep[pos[:, 0] >= 160] == 1.0)
    free, _ = static_pool(img, None, default_config, np.random.default_rng(0))
    assert 0.15 < np.mean(free[:, 0] < 160) < 0.35
