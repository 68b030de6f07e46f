"""Flow over a span of frames: the camera motion composed over it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from appliance.vision import geometry as g
from appliance.vision.likelihood import CameraMotion
from appliance.vision.span import compose, span_motion

K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])


def motion(R: np.ndarray, t: np.ndarray, metric: bool = True) -> CameraMotion:
    return CameraMotion(R=R, t_dir=t / np.linalg.norm(t), t_m=t if metric else None,
                        standstill=False, K=K)


def poses(n: int) -> list[np.ndarray]:
    """World-from-camera poses of a camera driving a bend with pitch and roll wobble."""
    out = []
    for k in range(n):
        T = np.eye(4)
        T[:3, :3] = g.euler_to_matrix(np.array([0.01 * np.sin(k), 0.03 * k, 0.004 * np.cos(k)]))
        T[:3, 3] = [0.1 * k * k, 0.05 * k, 0.33 * k]
        out.append(T)
    return out


def test_span_motion_is_the_motion_between_the_first_and_last_pose() -> None:
    P = poses(5)
    steps = [motion(*g.relative_motion(a, b)) for a, b in itertools.pairwise(P)]
    earlier = tuple(reversed(steps[:-1]))          # newest first
    for frames in (1, 2, 4):
        span = span_motion(steps[-1], earlier, frames)
        R, t = g.relative_motion(P[4 - frames], P[4])
        np.testing.assert_allclose(span.R, R, atol=1e-12)
        assert span.t_m is not None
        np.testing.assert_allclose(span.t_m, t, atol=1e-12)
        np.testing.assert_allclose(span.t_dir, t / np.linalg.norm(t), atol=1e-12)
    # a point seen in the first frame is where the span's motion puts it in the last
    X0 = np.array([2.0, -1.0, 20.0])
    Xw = P[0][:3, :3] @ X0 + P[0][:3, 3]
    X4 = P[4][:3, :3].T @ (Xw - P[4][:3, 3])
    span = span_motion(steps[-1], earlier, 4)
    assert span.t_m is not None
    np.testing.assert_allclose(span.R @ X0 + span.t_m, X4, atol=1e-9)
    with pytest.raises(ValueError, match="needs 4 earlier motions, got 3"):
        span_motion(steps[-1], earlier, 5)


def test_compose_without_metric_translation_keeps_the_direction_of_equal_steps() -> None:
    R = g.euler_to_matrix(np.array([0.0, 0.02, 0.0]))
    t = np.array([0.0, 0.0, -1.0])
    both = compose(motion(R, t, metric=False), motion(R, t))
    assert both.t_m is None
    expect = R @ t + t
    np.testing.assert_allclose(both.t_dir, expect / np.linalg.norm(expect), atol=1e-12)
    np.testing.assert_allclose(both.R, R @ R, atol=1e-12)
    still = compose(CameraMotion(np.eye(3), np.zeros(3), None, True, K), motion(R, t))
    assert still.standstill
