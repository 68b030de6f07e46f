"""The simulator's images agree with its own truth and geometry.

* the projected truth box of an object matches the pixels the renderer drew for it;
* static world points, projected with the truth camera poses of frames k and k+1,
  are where Lucas-Kanade finds them (the world points come from intersecting pixel
  rays with the objects' boxes, independently of the renderer);
* occlusion is by depth, not by drawing order; faces beside the camera are clipped;
* texture pre-filtering (rip-map levels) keeps distant surfaces from aliasing, and the
  asphalt of a bend is tracked as well as a straight road's.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from appliance.sim import object_textures as ot
from appliance.sim import textures as tx
from appliance.sim.drive import SimStep, SimulatedDrive, drive_look
from appliance.sim.effects import Effects
from appliance.sim.look import Look
from appliance.sim.render import Renderer, RenderSettings
from appliance.sim.world import (
    FLAT,
    BoxSkin,
    FaceSet,
    StaticObject,
    box_faces,
    rect_face,
    yaw_matrix,
)
from appliance.vision.geometry import PinholeCamera, vehicle_from_camera

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)


def _id_box(ids: np.ndarray, obj: int) -> tuple[int, int, int, int] | None:
    ys, xs = np.nonzero(ids == obj)
    if len(xs) == 0:
        return None
    return int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())


@pytest.mark.parametrize(
    "scenario,offsets_s",
    [
        ("pedestrian_crossing_nearside", (0.0, 1.0, 3.5)),
        ("car_crossing_intersection", (0.2, 1.5, 3.0)),
        ("cyclist_crossing_intersection", (0.2, 2.0)),
    ],
)
def test_truth_box_matches_rendered_pixels(scenario: str, offsets_s: tuple[float, ...]) -> None:
    drive = SimulatedDrive(scenario, seed=1)
    compared = 0
    for off in offsets_s:
        step = drive.snapshot(drive.n_frames - 1 - int(round(off * 30)))
        for oid, rec in step.truth_frame["objects"].items():
            u0, v0, u1, v1 = rec["bbox"]
            drawn = _id_box(step.ids, int(oid))
            if drawn is None:
                assert rec["visible"] == 0.0
                continue
            # every pixel drawn for the object lies inside its truth box (pixels touched by an
            # edge are drawn, so allow the half pixel beyond the box and rasterisation)
            assert drawn[0] >= u0 - 1.5 and drawn[1] >= v0 - 1.5
            assert drawn[2] <= u1 + 1.5 and drawn[3] <= v1 + 1.5
            # unoccluded, the id buffer's samples (the fine render's) cover 97.5-99.9 % of
            # the silhouette rasterised at the frame's resolution
            if rec["visible"] < 0.97 or (u1 - u0) < 4 or (v1 - v0) < 4:
                continue
            # unoccluded: the drawn pixels span the truth box within 2 px on every side
            np.testing.assert_allclose(
                drawn, [u0, v0, u1, v1], atol=2.0, err_msg=f"{scenario} object {oid}"
            )
            compared += 1
    assert compared >= 3


def _ray_box(obj: StaticObject, origin: np.ndarray, ray: np.ndarray) -> np.ndarray | None:
    """First intersection of a ray with an object's box (slab method), world frame."""
    R = yaw_matrix(obj.yaw)
    L, W, H = obj.body.size
    c = R.T @ (origin - np.array([obj.x, obj.y, 0.0]))
    r = R.T @ ray
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (np.array([-L / 2, -W / 2, 0.0]) - c) / r
        t2 = (np.array([L / 2, W / 2, H]) - c) / r
    t_near, t_far = np.nanmax(np.minimum(t1, t2)), np.nanmin(np.maximum(t1, t2))
    if t_near > t_far or t_near <= 0:
        return None
    hit: np.ndarray = origin + t_near * ray
    return hit


def _clean(scenario: str, seed: int) -> Look:
    """The drive's own look with a perfect gray sensor (the camera and world as drawn)."""
    return dataclasses.replace(drive_look(scenario, seed), effects=Effects.none())


def _lk_errors(drive: SimulatedDrive, a: SimStep, b: SimStep) -> np.ndarray:
    cam = drive.camera
    boxes = {o.body.obj: o for o in drive.statics if o.body.kind in ("car", "building")}
    A = np.array(a.truth_frame["camera_pose"])
    B_inv = np.linalg.inv(np.array(b.truth_frame["camera_pose"]))
    corners = cv2.goodFeaturesToTrack(a.image, 600, 0.01, 6).reshape(-1, 2)
    pts, world = [], []
    for p in corners:
        u, v = int(round(p[0])), int(round(p[1]))
        obj = int(a.ids[v, u])
        window = a.ids[max(v - 8, 0) : v + 9, max(u - 8, 0) : u + 9]
        if obj not in boxes or np.any(window != obj):  # away from silhouette edges
            continue
        ray = A[:3, :3] @ np.array([(p[0] - cam.cx) / cam.fx, (p[1] - cam.cy) / cam.fy, 1.0])
        X = _ray_box(boxes[obj], A[:3, 3], ray)
        if X is not None:
            pts.append(p)
            world.append(X)
    P = np.array(pts, np.float32)
    predicted = cam.project(np.array(world) @ B_inv[:3, :3].T + B_inv[:3, 3])
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.001)
    found, st, _ = cv2.calcOpticalFlowPyrLK(  # type: ignore[call-overload]
        a.image, b.image, P, None, winSize=(11, 11), maxLevel=2, criteria=crit
    )
    back, st2, _ = cv2.calcOpticalFlowPyrLK(  # type: ignore[call-overload]
        b.image, a.image, found, None, winSize=(11, 11), maxLevel=2, criteria=crit
    )
    ok = (st[:, 0] == 1) & (st2[:, 0] == 1) & (np.linalg.norm(back - P, axis=1) < 0.1)
    err: np.ndarray = np.linalg.norm(found[ok] - predicted[ok], axis=1)
    return err


@pytest.mark.parametrize("scenario", ["bend_static", "car_crossing_intersection"])
def test_static_points_reproject_where_lucas_kanade_finds_them(scenario: str) -> None:
    # the intersection drive's last second: PTU panned, body bounce, car growing in view
    drive = SimulatedDrive(scenario, seed=3, duration=0.5, look=_clean(scenario, 3))
    steps = list(drive)
    errors = np.concatenate([_lk_errors(drive, steps[k], steps[k + 1]) for k in range(0, 14, 3)])
    assert len(errors) > 200
    assert np.median(errors) < 0.1
    assert np.percentile(errors, 90) < 0.3


def _road_lk_errors(drive: SimulatedDrive, a: SimStep, b: SimStep) -> np.ndarray:
    """LK as the appliance runs it (9 px window, 2 levels) on the lane's asphalt 12-50 m ahead,
    started where the truth poses put each road point in frame b: how far it moves off (px)."""
    cam = drive.camera
    A = np.array(a.truth_frame["camera_pose"])
    B_inv = np.linalg.inv(np.array(b.truth_frame["camera_pose"]))
    us, vs = np.meshgrid(np.arange(40.0, 600.0, 6.0), np.arange(cam.cy + 15.0, cam.cy + 60.0, 3.0))
    px = np.column_stack([us.ravel(), vs.ravel()])
    px = px[a.ids[px[:, 1].astype(int), px[:, 0].astype(int)] == 0]
    rays = np.column_stack(
        [(px[:, 0] - cam.cx) / cam.fx, (px[:, 1] - cam.cy) / cam.fy, np.ones(len(px))]
    ) @ A[:3, :3].T
    s = -A[2, 3] / rays[:, 2]  # the road plane z = 0
    X = A[:3, 3] + s[:, None] * rays
    lateral = np.min(np.hypot(X[:, :1] - drive.path.x, X[:, 1:2] - drive.path.y), axis=1)
    lane = (s > 0) & (lateral < 2.5)
    px, X = px[lane], X[lane]
    predicted = cam.project(X @ B_inv[:3, :3].T + B_inv[:3, 3])
    found, st, _ = cv2.calcOpticalFlowPyrLK(  # type: ignore[call-overload]
        a.image, b.image, px.astype(np.float32), predicted.astype(np.float32),
        winSize=(9, 9), maxLevel=2, flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    ok = st[:, 0] == 1
    err: np.ndarray = np.linalg.norm(found[ok] - predicted[ok], axis=1)
    return err


def test_asphalt_seen_diagonally_to_the_world_axes_tracks_as_on_a_straight_road() -> None:
    # the bend's last second: heading ~41 deg, so a texture on world axes would be filtered
    # by the bounding box of each pixel's footprint, smeared across the road into streaks
    # (LK off its truth by a median 0.9 px, p90 4.4 px); the road's own strips follow it
    drive = SimulatedDrive("bend_static", seed=3, duration=1.0, look=_clean("bend_static", 3))
    steps = list(drive)
    heading = float(drive.path.pose(drive.tau(steps[0].t))[2])
    assert abs(np.sin(2.0 * heading)) > 0.9
    errors = np.concatenate([_road_lk_errors(drive, steps[k], steps[k + 1]) for k in range(0, 28, 3)])
    assert len(errors) > 1000
    assert np.median(errors) < 0.3
    assert np.percentile(errors, 90) < 1.0


def _skin(tex: int) -> BoxSkin:
    return BoxSkin(tex, tex, tex, tex, tex)


def _textures() -> list[tx.Texture]:
    rng = np.random.default_rng(0)
    return [tx.asphalt(rng, size=256), ot.facade(rng, 0), ot.facade(rng, 1)]


def _camera_from_world(y: float = 0.0) -> np.ndarray:
    return np.linalg.inv(vehicle_from_camera((0.0, y, 1.3), 0.0, 0.0, 0.0))


def _street(textures: list[tx.Texture]) -> tuple[FaceSet, FaceSet, FaceSet]:
    """A long facade whose nearest point is nearer than the car parked in front of it (a
    painter's order by distance would draw the facade over the car), and a pedestrian hidden
    by the car: (facade, car, pedestrian), object ids 1001, 101 and 1."""
    wall = box_faces(30.0, 1.0, 12.0, _skin(1), textures, 1001).transformed(
        np.eye(3), np.array([25.0, -7.5, 0])
    )
    car = box_faces(4.4, 1.8, 1.45, _skin(2), textures, 101).transformed(
        np.eye(3), np.array([28.0, -2.6, 0])
    )
    ped = box_faces(0.35, 0.55, 1.2, _skin(2), textures, 1).transformed(
        np.eye(3), np.array([33.0, -3.0, 0])
    )
    return wall, car, ped


def test_occlusion_is_by_depth_where_a_painters_order_fails() -> None:
    textures = _textures()
    wall, car, ped = _street(textures)
    for sets in ([wall, car, ped], [ped, car, wall]):
        _, ids = Renderer(CAM, textures, 0).render(_camera_from_world(), sets)
        u, v = CAM.project(np.array([[2.6, 0.6, 28.0 - 2.2]]))[
            0
        ]  # the car's rear face, camera frame
        assert ids[int(round(v)), int(round(u))] == 101
        drawn = _id_box(ids, 101)
        assert drawn is not None
        assert np.count_nonzero(ids == 101) > 0.9 * (drawn[2] - drawn[0] + 1) * (
            drawn[3] - drawn[1] + 1
        )
        assert np.count_nonzero(ids == 1001) > 10000
        assert np.count_nonzero(ids == 1) == 0


def test_faces_beside_the_camera_are_clipped_at_the_near_plane() -> None:
    textures = _textures()
    # a wall on the right that starts behind the camera and runs far ahead
    wall = FaceSet.from_quads(
        [
            rect_face(
                np.array([20.0, -2.0, 2.0]),
                np.array([0, 1.0, 0]),
                np.array([0, 0, -1.0]),
                50.0,
                4.0,
                1,
                textures,
                obj=5,
            )
        ]
    )
    img, ids = Renderer(CAM, textures, 0).render(_camera_from_world(), [wall])
    ys, xs = np.nonzero(ids == 5)
    assert len(xs) > 10000
    assert xs.min() > CAM.cx  # nothing wrapped round to the left half
    assert ids[240, 639] == 5 and ids[5, 639] == 5  # reaches the right edge, top to bottom


def test_prefiltered_levels_keep_distant_texture_from_aliasing() -> None:
    """A fronto-parallel asphalt wall 42 m away (6 texels per pixel), camera sliding 0.3 px per
    frame: Lucas-Kanade measures the true shift on the rip-mapped rendering; without
    pre-filtering (level 0 always) the aliasing shows up as false flow."""
    textures = [tx.asphalt(np.random.default_rng(1))]
    wall = FaceSet.from_quads(
        [
            rect_face(
                np.array([42.0, 0, 5]),
                np.array([-1.0, 0, 0]),
                np.array([0, 0, -1.0]),
                80,
                40,
                0,
                textures,
                obj=7,
            )
        ]
    )
    p90 = {}
    for bias in (0.5, -20.0):
        r = Renderer(
            CAM, textures, 0,
            RenderSettings(lod_bias=bias, fog_start_m=500.0, far_m=600.0, supersample=1),
        )
        frames = [
            r.render(_camera_from_world(-0.3 * k * 42.0 / 700.0), [wall])[0] for k in range(6)
        ]
        errs = []
        for a, b in zip(frames, frames[1:]):
            pts = cv2.goodFeaturesToTrack(a, 300, 0.01, 10)
            nxt, st, _ = cv2.calcOpticalFlowPyrLK(  # type: ignore[call-overload]
                a, b, pts, None, winSize=(11, 11), maxLevel=2
            )
            flow = (nxt - pts).reshape(-1, 2)[st[:, 0] == 1]
            errs.append(np.abs(flow[:, 0] + 0.3))
        p90[bias] = float(np.percentile(np.concatenate(errs), 90))
    assert p90[0.5] < 0.08
    assert p90[-20.0] > 2.0 * p90[0.5]


def test_supersampling_keeps_a_slanted_edge_from_crawling() -> None:
    """A dark wall's edge leaning 7 deg from the vertical, the camera moving 0.3 px per frame
    sideways: drawn with binary masks at the frame's resolution the edge is a staircase whose
    steps jump ~8 px along it as it moves, and LK follows the steps; rendered twice as finely
    and filtered down the edge moves as it should."""
    textures = [tx.asphalt(np.random.default_rng(0), size=256)]
    a = np.radians(7.0)
    wall = FaceSet.from_quads([rect_face(np.array([20.0, -6.0, 1.3]), np.array([-1.0, 0, 0]),
                                         np.array([0.0, np.sin(a), -np.cos(a)]), 12.0, 6.0, FLAT,
                                         textures, obj=3, value=60.0)])
    median = {}
    for ss in (1, 2):
        r = Renderer(CAM, textures, 0, RenderSettings(supersample=ss))
        frames = [r.render(_camera_from_world(-0.3 * k * 20.0 / 700.0), [wall])[0] for k in range(6)]
        errs = []
        for f0, f1 in zip(frames, frames[1:]):
            vs, us = np.nonzero(np.abs(cv2.Sobel(f0, cv2.CV_32F, 1, 0)[160:230, :400]) > 100)
            pts = np.ascontiguousarray(np.column_stack([us, vs + 160]).astype(np.float32)[::3])
            nxt, st, _ = cv2.calcOpticalFlowPyrLK(  # type: ignore[call-overload]
                f0, f1, pts, None, winSize=(9, 9), maxLevel=2
            )
            flow = (nxt - pts)[st[:, 0] == 1]
            errs.append(np.hypot(flow[:, 0] + 0.3, flow[:, 1]))   # truth: 0.3 px to the left
        median[ss] = float(np.median(np.concatenate(errs)))
    assert median[1] > 2.0
    assert median[2] < 0.5


def test_wrapping_textures_tile_seamlessly_at_every_level() -> None:
    rng = np.random.default_rng(2)
    for tex in (tx.asphalt(rng, size=256), tx.paving(rng), ot.facade(rng, 1)):
        base = tex.levels[0][0]
        tiled = tx.make_texture("tiled", np.tile(base, (2, 2)), True)
        for lu in range(len(tex.levels)):
            for lv in range(len(tex.levels[lu])):
                # down-sampling commutes with tiling: every level repeats exactly
                np.testing.assert_array_equal(
                    tiled.levels[lu][lv], np.tile(tex.levels[lu][lv], (2, 2))
                )
    noise = tx.asphalt(rng, size=256).levels[0][0].astype(float)
    seam = np.abs(noise[:, 0] - noise[:, -1]).mean()
    inner = np.abs(np.diff(noise, axis=1)).mean()
    assert seam < 1.5 * inner  # no discontinuity where the generated noise wraps


def _left_edges(frames: list[np.ndarray], rows: slice, level: float) -> np.ndarray:
    """Per frame, where a dark object's left edge crosses ``level`` (px, sub-pixel, linear
    between the two pixels around the crossing), averaged over ``rows``."""
    out = []
    for f in frames:
        xs = []
        for row in f[rows].astype(float):
            c = int(np.argmax(row < level))
            xs.append(c - 1 + (row[c - 1] - level) / (row[c - 1] - row[c]))
        out.append(np.mean(xs))
    return np.array(out)


def test_a_movers_silhouette_moves_smoothly_not_in_half_pixel_steps() -> None:
    """A dark pedestrian-sized face 20 m ahead in front of a bright wall, moving 0.1 px per
    frame across the image. Drawn as a static face (binary masks at twice the resolution)
    its edge stands still and then jumps half a pixel; drawn as a mover (its coverage of
    each pixel) it moves 0.1 px every frame, as on a sensor."""
    textures = _textures()
    wall = FaceSet.from_quads([rect_face(np.array([30.0, 0.0, 3.0]), np.array([-1.0, 0, 0]),
                                         np.array([0.0, 0, -1.0]), 30.0, 10.0, FLAT, textures,
                                         obj=2, value=200.0)])
    step_m = 0.1 * 20.0 / CAM.fx          # 0.1 px per frame at 20 m

    def person(k: int) -> FaceSet:
        return FaceSet.from_quads([rect_face(np.array([20.0, 0.3 - k * step_m, 0.9]),
                                             np.array([-1.0, 0, 0]), np.array([0.0, 0, -1.0]),
                                             0.6, 1.7, FLAT, textures, obj=1, value=40.0)])

    r = Renderer(CAM, textures, 0)
    soft = [r.render(_camera_from_world(), [wall], [person(k)])[0] for k in range(11)]
    hard = [r.render(_camera_from_world(), [wall, person(k)])[0] for k in range(11)]
    rows = slice(230, 260)
    soft_steps = np.diff(_left_edges(soft, rows, 120.0))
    hard_steps = np.diff(_left_edges(hard, rows, 120.0))
    # every frame a step (its size quantised by the coverage mask's 8 x 8 samples per pixel
    # here, and by the edge measure), and 1 px over the ten frames
    assert np.all((soft_steps > 0.03) & (soft_steps < 0.2))
    assert abs(np.sum(soft_steps) - 1.0) < 0.05
    assert np.count_nonzero(np.abs(hard_steps) < 0.02) >= 5    # standing still ...
    assert np.max(np.abs(hard_steps)) > 0.4                    # ... then jumping
    # the interior is drawn as before, and the pixel centres it covers carry its id
    _, ids_soft = r.render(_camera_from_world(), [wall], [person(3)])
    _, ids_hard = r.render(_camera_from_world(), [wall, person(3)])
    np.testing.assert_array_equal(ids_soft, ids_hard)
    np.testing.assert_array_equal(soft[3][rows, 330:338], hard[3][rows, 330:338])


def test_a_mover_hidden_by_a_static_object_does_not_show_through() -> None:
    textures = _textures()
    wall, car, ped = _street(textures)
    r = Renderer(CAM, textures, 0)
    with_ped, ids = r.render(_camera_from_world(), [wall, car], [ped])
    without, ids_without = r.render(_camera_from_world(), [wall, car])
    np.testing.assert_array_equal(with_ped, without)
    np.testing.assert_array_equal(ids, ids_without)
    # in the open, the same pedestrian is drawn, over the wall
    seen, ids_seen = r.render(_camera_from_world(), [wall], [ped])
    assert np.count_nonzero(ids_seen == 1) > 50
    assert np.count_nonzero(seen != r.render(_camera_from_world(), [wall])[0]) > 50
