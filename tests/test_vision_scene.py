"""A tiny ray-cast scene for the vision tests (textured road, backdrop, moving boxes), and its checks.

Other ``test_vision_*`` files import :func:`render` and :class:`Scene` from here. The
scene is independent of the simulator: the road is the plane z = 0 of the world
(ISO 8855 axes), a textured backdrop stands at ``wall_x_m``, and boxes are
textured vertical rectangles facing the camera that move at constant velocity.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig, load_config
from appliance.vision import geometry as g
from appliance.vision.flow import Tracks, corner_candidates, track


def noise_texture(seed: int, size: int = 512) -> NDArray[np.float32]:
    """Periodic 1/f noise (size, size), mean 128, std 45: texture at every scale, no seams."""
    rng = np.random.default_rng(seed)
    f = np.fft.fftfreq(size)
    radius = np.hypot(f[:, None], f[None, :])
    spectrum = np.fft.fft2(rng.standard_normal((size, size))) / (radius + 2.0 / size)
    tex = np.real(np.fft.ifft2(spectrum))
    tex = (tex - tex.mean()) / tex.std() * 45.0 + 128.0
    return tex.astype(np.float32)


@dataclass(frozen=True)
class Box:
    """Vertical rectangle facing the camera: front face at world x, centred at y, z from 0 to height."""

    x_m: float
    y_m: float
    width_m: float
    height_m: float
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0

    def at(self, t: float) -> Box:
        return Box(self.x_m + self.vx_m_s * t, self.y_m + self.vy_m_s * t, self.width_m,
                   self.height_m, self.vx_m_s, self.vy_m_s)


@dataclass(frozen=True)
class Scene:
    road_px_per_m: float = 40.0
    wall_x_m: float = 90.0
    wall_px_per_m: float = 8.0
    box_px_per_m: float = 60.0
    boxes: tuple[Box, ...] = ()
    textures: tuple[tuple[NDArray[np.float32], ...], ...] = field(default_factory=lambda: default_textures())


LEVELS = 7


def mip(tex: NDArray[np.float32]) -> tuple[NDArray[np.float32], ...]:
    """Prefiltered copies of a periodic texture, level L blurred to a footprint of 2^L texels."""
    f = np.fft.fftfreq(tex.shape[0])
    r2 = f[:, None] ** 2 + f[None, :] ** 2
    spectrum = np.fft.fft2(tex)
    out = [tex]
    for level in range(1, LEVELS):
        sigma = 0.5 * 2.0**level
        out.append(np.real(np.fft.ifft2(spectrum * np.exp(-2.0 * np.pi**2 * sigma**2 * r2)))
                   .astype(np.float32))
    return tuple(out)


@functools.lru_cache(maxsize=1)
def default_textures() -> tuple[tuple[NDArray[np.float32], ...], ...]:
    """Road, backdrop and box textures (mip levels of each), computed once."""
    return tuple(mip(noise_texture(seed)) for seed in (1, 2, 3))


def _lookup(levels: tuple[NDArray[np.float32], ...], a: NDArray[np.float64], b: NDArray[np.float64],
            scale: float) -> NDArray[np.float64]:
    """Anti-aliased texture at surface coordinates a, b (H, W) m: level from the pixel footprint."""
    n = levels[0].shape[0]
    ta, tb = a * scale, b * scale
    foot = np.ones_like(ta)
    for arr in (ta, tb):
        for axis in (0, 1):
            gr = np.abs(np.gradient(np.nan_to_num(arr, nan=0.0, posinf=0.0, neginf=0.0), axis=axis))
            foot = np.maximum(foot, np.where(np.isfinite(gr), gr, 0.0))
    level = np.clip(np.log2(foot), 0.0, LEVELS - 1.0)
    with np.errstate(invalid="ignore"):
        mx = np.nan_to_num(np.mod(ta, n), nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
        my = np.nan_to_num(np.mod(tb, n), nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)
    lo = np.floor(level).astype(int)
    frac = level - lo
    out = np.zeros_like(ta)
    for k in range(LEVELS):
        near = (lo == k) | (lo + 1 == k)
        if not near.any():
            continue
        val = cv2.remap(levels[k], mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        wk = np.where(lo == k, 1.0 - frac, np.where(lo + 1 == k, frac, 0.0))
        out += wk * val
    return out


def render(camera: g.PinholeCamera, world_from_cam: NDArray[np.float64], scene: Scene,
           t: float = 0.0) -> NDArray[np.uint8]:
    """8-bit gray image (H, W) of the scene seen from ``world_from_cam`` (4x4) at time t (s)."""
    h, w = camera.height, camera.width
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    d = (camera.rays(np.column_stack([u.ravel(), v.ravel()])) @ world_from_cam[:3, :3].T).reshape(h, w, 3)
    o = world_from_cam[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_road = np.where(d[..., 2] < -1e-9, -o[2] / d[..., 2], np.inf)
        lam_wall = np.where(d[..., 0] > 1e-9, (scene.wall_x_m - o[0]) / d[..., 0], np.inf)
        p_road = o + lam_road[..., None] * d
        p_wall = o + lam_wall[..., None] * d
    mips = scene.textures
    lam = np.minimum(lam_road, lam_wall)
    img = np.where(lam_road <= lam_wall,
                   _lookup(mips[0], p_road[..., 0], p_road[..., 1], scene.road_px_per_m),
                   _lookup(mips[1], p_wall[..., 1], p_wall[..., 2], scene.wall_px_per_m))
    img = np.where(np.isfinite(lam), img, 128.0)
    for k, box in enumerate(b.at(t) for b in scene.boxes):
        with np.errstate(divide="ignore", invalid="ignore"):
            lam_box = np.where(d[..., 0] > 1e-9, (box.x_m - o[0]) / d[..., 0], np.inf)
            q = o + lam_box[..., None] * d
        hit = ((lam_box < lam) & (np.abs(q[..., 1] - box.y_m) <= box.width_m / 2)
               & (q[..., 2] >= 0.0) & (q[..., 2] <= box.height_m))
        look = _lookup(mips[2], q[..., 1] - box.y_m + 7.0 * k, q[..., 2], scene.box_px_per_m)
        img = np.where(hit, 0.6 * look + 70.0, img)
        lam = np.where(hit, lam_box, lam)
    return np.clip(img, 0, 255).astype(np.uint8)


def box_bbox(camera: g.PinholeCamera, world_from_cam: NDArray[np.float64], box: Box) -> tuple[float, float, float, float]:
    """Image box (u0, v0, u1, v1) of a box's front face."""
    corners = np.array([[box.x_m, box.y_m + sy * box.width_m / 2, z, 1.0]
                        for sy in (-1, 1) for z in (0.0, box.height_m)])
    cam = (np.linalg.inv(world_from_cam) @ corners.T).T[:, :3]
    uv = camera.project(cam)
    return (float(uv[:, 0].min()), float(uv[:, 1].min()), float(uv[:, 0].max()), float(uv[:, 1].max()))


CAMERA = g.PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
MOUNT = (1.9, 0.0, 1.3)


def pose(x_m: float, pitch_rad: float = 0.0, yaw_rad: float = 0.0) -> NDArray[np.float64]:
    """World-from-camera pose of a vehicle at (x_m, 0) with heading yaw and extra body pitch."""
    vehicle = np.eye(4)
    vehicle[:3, :3] = g.rot_z(yaw_rad) @ g.rot_y(pitch_rad)
    vehicle[0, 3] = x_m
    return vehicle @ g.vehicle_from_camera(MOUNT, 0.0, 0.0, 0.0)


def test_render_puts_a_box_where_the_camera_model_projects_it() -> None:
    scene = Scene(boxes=(Box(20.0, 2.0, 1.0, 1.8),))
    T = pose(0.0)
    img = render(CAMERA, T, scene)
    u0, v0, u1, v1 = box_bbox(CAMERA, T, scene.boxes[0])
    assert u1 < CAMERA.cx and v1 > CAMERA.cy > v0      # left of centre, straddles the horizon
    inside = img[int(v0) + 3:int(v1) - 3, int(u0) + 3:int(u1) - 3].astype(float)
    outside = render(CAMERA, T, Scene())[int(v0) + 3:int(v1) - 3, int(u0) + 3:int(u1) - 3]
    assert np.mean(np.abs(inside - outside)) > 10.0


def test_lucas_kanade_measures_the_flow_of_a_known_camera_motion() -> None:
    cfg: FlowConfig = load_config().flow
    T0, T1 = pose(0.0), pose(0.2, pitch_rad=0.003)   # 6 m/s at 30 frames/s, and a bump
    img0, img1 = render(CAMERA, T0, Scene()), render(CAMERA, T1, Scene())
    pts, _ = corner_candidates(img0, 24)
    below = pts[(pts[:, 1] > 270) & (pts[:, 1] < 400)]   # road flows up to ~12 px
    tr = track(img0, img1, below, np.ones(len(below), bool), cfg)
    assert tr.valid.mean() > 0.8
    # true flow of road points: intersect the rays with the road, project into frame 1
    rays = CAMERA.rays(below) @ T0[:3, :3].T
    lam = -T0[2, 3] / rays[:, 2]
    world = T0[:3, 3] + lam[:, None] * rays
    cam1 = (np.linalg.inv(T1) @ np.column_stack([world, np.ones(len(world))]).T).T[:, :3]
    truth = CAMERA.project(cam1)
    err = tr.end[tr.valid] - truth[tr.valid]
    # the road's flow is strongly sheared, which LK's translation model only approximates:
    # noisy (about 4 % of a 5 px flow) but unbiased
    assert np.median(np.linalg.norm(err, axis=1)) < 0.25
    assert np.all(np.abs(np.median(err, axis=0)) < 0.03)


def test_a_guess_lets_lk_follow_a_fast_pan_and_changes_nothing_at_the_point_itself() -> None:
    """A 20 px shift (a PTU pan of ~2 deg in a frame) is beyond the pyramid's reach from the
    point itself for many points; from the prior rotation's guess (1 px off) every point is
    tracked. A guess at the point itself gives exactly the unguided result, backward check
    included: OpenCV writes its answer into the initial-flow array, and a backward search
    started from there (at the answer) would pass every track."""
    cfg: FlowConfig = load_config().flow
    img0 = np.clip(cv2.resize(noise_texture(7), (640, 480)), 0, 255).astype(np.uint8)
    img1 = np.asarray(cv2.warpAffine(img0, np.array([[1, 0, 20], [0, 1, 0]], dtype=np.float32),
                                     (640, 480), borderMode=cv2.BORDER_REFLECT), dtype=np.uint8)
    pts = np.random.default_rng(1).uniform([60, 40], [560, 440], (300, 2))
    check = np.ones(len(pts), bool)
    truth = pts + [20.0, 0.0]

    def right(tr: Tracks) -> NDArray[np.bool_]:
        return np.asarray(tr.valid & (np.linalg.norm(tr.end - truth, axis=1) < 0.2))

    plain = track(img0, img1, pts, check, cfg)
    guided = track(img0, img1, pts, check, cfg, guess=pts + [19.0, 0.5])
    assert right(guided).mean() > 0.98
    assert right(plain).mean() < 0.8 and (plain.valid & ~right(plain)).sum() < 0.05 * len(pts)
    at_point = track(img0, img1, pts, check, cfg, guess=pts)
    np.testing.assert_array_equal(at_point.valid, plain.valid)
    np.testing.assert_array_equal(at_point.fb_error, plain.fb_error)


def test_a_window_reaching_over_the_image_border_gives_no_flow() -> None:
    """Texture shifted 3 px left, as the road flows out of the image: points whose LK window
    (9 px) would reach over the border, at the start or at the end, are not valid, while the
    same shift is tracked right a window's half further in."""
    cfg: FlowConfig = load_config().flow
    img0 = np.clip(cv2.resize(noise_texture(7), (640, 480)), 0, 255).astype(np.uint8)
    img1 = np.asarray(cv2.warpAffine(img0, np.array([[1, 0, -3], [0, 1, 0]], dtype=np.float32),
                                     (640, 480), borderMode=cv2.BORDER_REFLECT), dtype=np.uint8)
    u = np.array([1.0, 3.0, 6.0, 8.0, 9.0, 20.0, 636.0])
    pts = np.column_stack([u, np.full(len(u), 240.0)])
    tr = track(img0, img1, pts, np.ones(len(pts), bool), cfg)
    half = cfg.window_px // 2
    inside = (u >= half) & (u - 3.0 >= half) & (u <= 639 - half)
    np.testing.assert_array_equal(tr.valid, inside)
    np.testing.assert_allclose(tr.end[tr.valid, 0], u[inside] - 3.0, atol=0.1)
