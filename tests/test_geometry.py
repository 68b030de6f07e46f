"""The camera model on its own: a sign error shared by simulator and vision would cancel out."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from appliance.vision import geometry as g


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("angle", [-0.3, 0.01, 0.7])
def test_single_axis_euler_matches_rodrigues(axis: int, angle: float) -> None:
    r = np.zeros(3)
    r[axis] = angle
    R_cv, _ = cv2.Rodrigues(r)
    np.testing.assert_allclose(g.euler_to_matrix(r), R_cv, atol=1e-12)


def test_euler_order_is_z_y_x_and_round_trips() -> None:
    r = np.array([0.1, -0.2, 0.3])
    R = g.euler_to_matrix(r)
    expected = (
        cv2.Rodrigues(np.array([0, 0, 0.3]))[0]
        @ cv2.Rodrigues(np.array([0, -0.2, 0]))[0]
        @ cv2.Rodrigues(np.array([0.1, 0, 0]))[0]
    )
    np.testing.assert_allclose(R, expected, atol=1e-12)
    np.testing.assert_allclose(g.matrix_to_euler(R), r, atol=1e-12)
    batch = np.array([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]])
    assert g.euler_to_matrix(batch).shape == (2, 3, 3)


def test_vehicle_axes_seen_from_the_camera() -> None:
    Rvc = g.vehicle_from_camera_rotation(0.0, 0.0, 0.0)
    # camera forward (z) is vehicle forward (x), camera right (x) is vehicle -y, camera down is -z
    np.testing.assert_allclose(Rvc @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(Rvc @ [1, 0, 0], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(Rvc @ [0, 1, 0], [0, 0, -1], atol=1e-12)


def test_pan_left_tilt_up_pitch_down() -> None:
    fwd = np.array([0.0, 0.0, 1.0])
    assert (g.vehicle_from_camera_rotation(0.0, 0.2, 0.0) @ fwd)[1] > 0.19  # pan + looks left
    assert (g.vehicle_from_camera_rotation(0.0, 0.0, 0.2) @ fwd)[2] > 0.19  # tilt + looks up
    assert (g.vehicle_from_camera_rotation(0.2, 0.0, 0.0) @ fwd)[2] < -0.19  # pitch + looks down


def test_point_ahead_left_and_above_projects_up_left() -> None:
    cam = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
    T = g.vehicle_from_camera((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
    p_vehicle = np.array([21.9, 2.0, 2.3, 1.0])  # 20 m ahead, 2 m left, 1 m above the camera
    p_cam = np.linalg.inv(T) @ p_vehicle
    uv = cam.project(p_cam[:3])[0]
    np.testing.assert_allclose(uv, [319.5 - 70.0, 239.5 - 35.0], atol=1e-9)


def test_projection_with_distortion_matches_opencv_and_undistort_inverts_it() -> None:
    cam = g.PinholeCamera(640, 480, 600.0, 610.0, 320.0, 240.0, (-0.2, 0.05, 0.001, -0.001, 0.0))
    P = np.array([[0.5, -0.3, 4.0], [-1.0, 0.8, 6.0], [0.0, 0.0, 3.0]])
    uv = cam.project(P)
    ref, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), cam.K, np.array(cam.distortion))
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=1e-9)
    rays = cam.rays(uv)
    np.testing.assert_allclose(rays, P / P[:, 2:3], atol=1e-6)


def test_points_behind_the_camera_are_nan() -> None:
    cam = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
    uv = cam.project(np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]]))
    assert np.isnan(uv[0]).all() and np.isfinite(uv[1]).all()


def test_rotational_flow_is_depth_independent_and_matches_projection() -> None:
    cam = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
    R = g.euler_to_matrix(np.array([0.01, -0.02, 0.005]))
    rng = np.random.default_rng(1)
    dirs = np.column_stack([rng.uniform(-0.4, 0.4, 20), rng.uniform(-0.3, 0.3, 20), np.ones(20)])
    for depth in (2.0, 50.0):
        P = dirs * depth
        uv0 = cam.project(P)
        uv1 = cam.project(P @ R.T)  # pure rotation, t = 0
        np.testing.assert_allclose(g.rotational_flow(cam, uv0, R), uv1 - uv0, atol=1e-9)


def test_rotate_pixels_moves_distorted_pixels_where_the_rotated_points_project() -> None:
    """The LK guess: image (distorted) pixels of points at any depth, after a pure rotation."""
    cam = g.PinholeCamera(640, 480, 600.0, 610.0, 320.0, 240.0, (-0.2, 0.05, 0.001, -0.001, 0.0))
    R = g.euler_to_matrix(np.array([0.004, -0.026, 0.002]))    # a 1.5 deg pan
    rng = np.random.default_rng(2)
    P = np.column_stack([rng.uniform(-0.4, 0.4, 30), rng.uniform(-0.3, 0.3, 30), np.ones(30)])
    P *= rng.uniform(2.0, 80.0, 30)[:, None]
    uv0, uv1 = cam.project(P), cam.project(P @ R.T)
    np.testing.assert_allclose(g.rotate_pixels(cam, uv0, R), uv1, atol=1e-4)
    assert np.isnan(g.rotate_pixels(cam, uv0[:1], g.rot_y(np.pi))).all()   # turned behind


def test_epipole_of_forward_motion_is_the_focus_of_expansion() -> None:
    cam = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
    e = g.epipole(cam, np.array([0.0, 0.0, -1.0]))
    np.testing.assert_allclose(e, [319.5, 239.5])
    # static points move away from it when the camera moves forward (t_z < 0)
    P = np.array([[1.0, 0.5, 10.0]])
    t = np.array([0.0, 0.0, -0.5])
    uv0, uv1 = cam.project(P), cam.project(P + t)
    assert np.dot(uv1[0] - uv0[0], uv0[0] - e) > 0
    assert g.epipole(cam, np.array([1.0, 0.0, 0.0])) is None


def test_relative_motion_from_poses() -> None:
    R1 = g.euler_to_matrix(np.array([0.0, 0.1, 0.0]))
    A = np.eye(4)
    A[:3, :3] = R1
    A[:3, 3] = [1.0, 2.0, 3.0]
    B = np.eye(4)
    B[:3, :3] = g.euler_to_matrix(np.array([0.02, 0.12, -0.01]))
    B[:3, 3] = [1.5, 2.0, 3.2]
    R, t = g.relative_motion(A, B)
    X_world = np.array([4.0, -1.0, 20.0])
    X1 = A[:3, :3].T @ (X_world - A[:3, 3])
    X2 = B[:3, :3].T @ (X_world - B[:3, 3])
    np.testing.assert_allclose(R @ X1 + t, X2, atol=1e-12)


def test_in_image_uses_pixel_centres_and_rejects_nan() -> None:
    uv = np.array([[0.0, 0.0], [639.0, 479.0], [639.01, 10.0], [-0.01, 10.0], [10.0, 479.5],
                   [np.nan, 10.0]])
    assert g.in_image(uv, 640, 480).tolist() == [True, True, False, False, False, False]
