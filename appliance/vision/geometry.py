"""Camera model and frame conventions shared by the vision core and the simulator.

Conventions (spec/interfaces.md):

* Camera frame (OpenCV): x right, y down, z forward; pixel (u, v) origin at the
  centre of the top-left pixel.
* Vehicle frame (ISO 8855): x forward, y left, z up; origin on the road below the
  middle of the rear axle.
* Pan positive turns the camera left (same sense as yaw), tilt positive looks
  up, mount pitch positive looks down.
* Euler angles ``r = (r_x, r_y, r_z)`` (rad) describe ``R = Rz(r_z) @ Ry(r_y) @ Rx(r_x)``.
* Camera motion between two frames is ``(R, t)`` with ``X_cur = R @ X_prev + t``
  for a static point in camera coordinates; the epipole in the current image is
  the projection of the previous camera centre, ``K @ t``.

Everything here is pure numpy (OpenCV only where it does the same job better),
vectorised over points, and has no state.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# Rotation taking camera axes to PTU-head axes (head axes = vehicle axes when the
# PTU is at zero and the mount is level): camera z (forward) -> head x,
# camera x (right) -> head -y, camera y (down) -> head -z.
HEAD_FROM_CAMERA: FloatArray = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def rot_x(a: float) -> FloatArray:
    """Rotation by ``a`` rad about the x axis (right-handed)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> FloatArray:
    """Rotation by ``a`` rad about the y axis (right-handed)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> FloatArray:
    """Rotation by ``a`` rad about the z axis (right-handed)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_to_matrix(r: NDArray[np.floating]) -> FloatArray:
    """``R = Rz(r_z) Ry(r_y) Rx(r_x)`` for Euler angles ``r`` of shape (..., 3), rad.

    Vectorised: returns shape (..., 3, 3).
    """
    r = np.asarray(r, dtype=np.float64)
    c, s = np.cos(r), np.sin(r)   # one call each: LM builds these for batches of small states
    cx, cy, cz = c[..., 0], c[..., 1], c[..., 2]
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    czsy, szsy = cz * sy, sz * sy
    R = np.empty(r.shape[:-1] + (3, 3))
    R[..., 0, 0] = cz * cy
    R[..., 0, 1] = czsy * sx - sz * cx
    R[..., 0, 2] = czsy * cx + sz * sx
    R[..., 1, 0] = sz * cy
    R[..., 1, 1] = szsy * sx + cz * cx
    R[..., 1, 2] = szsy * cx - cz * sx
    R[..., 2, 0] = -sy
    R[..., 2, 1] = cy * sx
    R[..., 2, 2] = cy * cx
    return R


def matrix_to_euler(R: NDArray[np.floating]) -> FloatArray:
    """Inverse of :func:`euler_to_matrix` (r_y in [-pi/2, pi/2]); shape (..., 3)."""
    R = np.asarray(R, dtype=np.float64)
    rx = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    ry = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    rz = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([rx, ry, rz], axis=-1)


def rotation_angle(R: NDArray[np.floating]) -> FloatArray:
    """Angle (rad) of the rotation R, shape (...)."""
    R = np.asarray(R, dtype=np.float64)
    c = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.asarray(np.arccos(np.clip(c, -1.0, 1.0)), dtype=np.float64)


def vehicle_from_camera_rotation(pitch_rad: float, pan_rad: float, tilt_rad: float) -> FloatArray:
    """Rotation taking camera coordinates to vehicle coordinates.

    The PTU base is pitched down by ``pitch_rad`` (rotation about vehicle +y);
    pan turns about the base's up axis (positive = left); tilt turns about the
    panned left axis (positive = up, hence the minus sign).
    """
    return rot_y(pitch_rad) @ rot_z(pan_rad) @ rot_y(-tilt_rad) @ HEAD_FROM_CAMERA


def vehicle_from_camera(
    position_m: tuple[float, float, float], pitch_rad: float, pan_rad: float, tilt_rad: float
) -> FloatArray:
    """4x4 transform taking camera coordinates to vehicle coordinates.

    ``position_m`` is the camera centre in the vehicle frame (the mount's x, y, z).
    """
    T = np.eye(4)
    T[:3, :3] = vehicle_from_camera_rotation(pitch_rad, pan_rad, tilt_rad)
    T[:3, 3] = position_m
    return T


def relative_motion(
    world_from_prev: NDArray[np.floating], world_from_cur: NDArray[np.floating]
) -> tuple[FloatArray, FloatArray]:
    """Camera motion ``(R, t)`` with ``X_cur = R X_prev + t`` from two 4x4 poses.

    Poses are world-from-camera transforms (as in ``truth.json``'s ``camera_poses``).
    """
    A = np.asarray(world_from_prev, dtype=np.float64)
    B = np.asarray(world_from_cur, dtype=np.float64)
    Rb_t = B[:3, :3].T
    R = Rb_t @ A[:3, :3]
    t = Rb_t @ (A[:3, 3] - B[:3, 3])
    return R, t


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole camera with OpenCV's k1 k2 p1 p2 k3 distortion.

    Pixel coordinates given to :meth:`project` and :meth:`rays` are *distorted*
    (as in the image); :meth:`undistort` turns them into ideal pinhole pixels,
    in which all the epipolar geometry of the vision core is done.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def K(self) -> FloatArray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def K_inv(self) -> FloatArray:
        return np.array(
            [
                [1.0 / self.fx, 0.0, -self.cx / self.fx],
                [0.0, 1.0 / self.fy, -self.cy / self.fy],
                [0.0, 0.0, 1.0],
            ]
        )

    @property
    def has_distortion(self) -> bool:
        return any(abs(k) > 0.0 for k in self.distortion)

    def project(self, points_cam: NDArray[np.floating]) -> FloatArray:
        """Project camera-frame points (N, 3) to image pixels (N, 2), distortion applied.

        Points with z <= 0 come out as NaN.
        """
        P = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
        out = np.full((P.shape[0], 2), np.nan)
        front = P[:, 2] > 1e-9
        if not np.any(front):
            return out
        if self.has_distortion:
            uv, _ = cv2.projectPoints(
                P[front], np.zeros(3), np.zeros(3), self.K, np.asarray(self.distortion, float)
            )
            out[front] = uv.reshape(-1, 2)
        else:
            Q = P[front]
            out[front, 0] = self.fx * Q[:, 0] / Q[:, 2] + self.cx
            out[front, 1] = self.fy * Q[:, 1] / Q[:, 2] + self.cy
        return out

    def undistort(self, uv: NDArray[np.floating]) -> FloatArray:
        """Image pixels (N, 2) -> ideal (undistorted) pinhole pixels (N, 2)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        if not self.has_distortion or uv.shape[0] == 0:
            return uv.copy()
        und = cv2.undistortPoints(
            uv.reshape(-1, 1, 2), self.K, np.asarray(self.distortion, float), P=self.K
        )
        return und.reshape(-1, 2).astype(np.float64)

    def rays(self, uv: NDArray[np.floating]) -> FloatArray:
        """Image pixels (N, 2) -> camera-frame rays (N, 3) with z = 1 (distortion removed)."""
        ideal = self.undistort(uv)
        return np.column_stack(
            [
                (ideal[:, 0] - self.cx) / self.fx,
                (ideal[:, 1] - self.cy) / self.fy,
                np.ones(len(ideal)),
            ]
        )


def in_image(uv: NDArray[np.floating], width: int, height: int, margin: float = 0.0
             ) -> NDArray[np.bool_]:
    """(N,) True where the pixels ``uv`` (N, 2) lie in a ``width`` x ``height`` image, pixel
    centres ``margin <= u <= width - 1 - margin``, likewise v (NaN: False)."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    return np.asarray((uv[:, 0] >= margin) & (uv[:, 0] <= width - 1.0 - margin)
                      & (uv[:, 1] >= margin) & (uv[:, 1] <= height - 1.0 - margin))


def rotational_flow(
    camera: PinholeCamera, uv: NDArray[np.floating], R: NDArray[np.floating]
) -> FloatArray:
    """Flow F_R (N, 2) that the rotation R alone induces at ideal pixels ``uv`` (N, 2).

    ``x' ~ K R K^-1 x``: independent of depth (section 2 of the paper).
    """
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    H = camera.K @ np.asarray(R, dtype=np.float64) @ camera.K_inv
    x = np.column_stack([uv, np.ones(len(uv))]) @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        moved = x[:, :2] / x[:, 2:3]
    return moved - uv


def rotate_pixels(camera: PinholeCamera, uv: NDArray[np.floating], R: NDArray[np.floating]
                  ) -> FloatArray:
    """Where the rotation R alone moves image pixels ``uv`` (N, 2): distorted in, distorted out
    (``x' ~ K R K^-1 x`` on the ideal pixels); NaN where the ray turns behind the camera."""
    ideal = camera.undistort(uv)
    rays = np.column_stack([ideal, np.ones(len(ideal))]) @ camera.K_inv.T
    return camera.project(rays @ np.asarray(R, dtype=np.float64).T)


def lk_start(camera: PinholeCamera, uv: NDArray[np.floating], R: NDArray[np.floating]) -> FloatArray:
    """Where a Lucas-Kanade search for pixels ``uv`` (N, 2) starts in the other frame, the
    camera having rotated by R from ``uv``'s frame to it: :func:`rotate_pixels`, or the pixel
    itself where that is undefined (the ray turned behind the camera)."""
    moved = rotate_pixels(camera, uv, R)
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    return np.where(np.isfinite(moved), moved, uv)


def epipole(camera: PinholeCamera, t: NDArray[np.floating], eps: float = 1e-9) -> FloatArray | None:
    """Epipole ``K t`` in ideal pixels (the FOE for forward motion), or None at infinity.

    ``t`` is the translation of the camera motion ``X_cur = R X_prev + t``; for a
    camera moving forward ``t_z < 0`` and static flow points away from the epipole.
    """
    t = np.asarray(t, dtype=np.float64)
    if abs(t[2]) < eps * max(1.0, float(np.linalg.norm(t))):
        return None
    e = camera.K @ t
    return np.asarray(e[:2] / e[2], dtype=np.float64)
