"""The occlusion test of a coasted track (decision/occlusion.py) on rendered image pairs.

A textured fronto-parallel wall at depth Z seen by a camera driving straight at it:
between two frames the wall's image is magnified about the principal point by
``Z_prev / Z_cur``, rendered here with OpenCV. The flow vision measures at the probe's
points (vision/probes.py) then says whether the wall is nearer than an object at a given
depth would be.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from appliance.config import Config
from appliance.decision import lost_tracks
from appliance.decision.cues import TrackCues
from appliance.decision.lost_tracks import LostTrack
from appliance.decision.occlusion import (
    CoastProbe,
    band_points,
    course_count,
    course_probe,
    cover_probe,
    head_band,
    probe_box,
    probe_points,
)
from appliance.decision.occlusion import cover_ratio as cover_from_flow
from appliance.decision.tracking import ImageTrack
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import FloatArray, PinholeCamera, matrix_to_euler
from appliance.vision.probes import PointFlow, measure_points

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
STEP_M = 0.4          # camera travel between the frames (12 m/s at 30 fps)
BOX = (420.0, 260.0, 470.0, 360.0)   # off the principal point: static flow 2-6 px


def texture(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (CAM.height, CAM.width)).astype(np.float32)
    return np.clip(cv2.GaussianBlur(noise, (0, 0), 1.5) * 2.0 - 128.0, 0, 255).astype(np.uint8)


def wall_pair(depth_cur: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Previous and current frame of a wall at ``depth_cur`` m now, ``STEP_M`` farther before."""
    prev = texture(seed)
    s = (depth_cur + STEP_M) / depth_cur
    c = np.array([CAM.cx, CAM.cy])
    A = np.array([[s, 0.0, (1 - s) * c[0]], [0.0, s, (1 - s) * c[1]]])
    cur = cv2.warpAffine(prev, A, (CAM.width, CAM.height), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REFLECT)
    return prev, cur


T_M = np.array([0.0, 0.0, -STEP_M])   # X_cur = X_prev + t: the camera moved forward


def measured(prev: np.ndarray, cur: np.ndarray, pts: FloatArray, R: np.ndarray, cfg: Config
             ) -> PointFlow:
    """The flow vision measures at ``pts`` of ``cur``, the camera having rotated by ``R``."""
    return measure_points(prev, cur, {0: pts}, matrix_to_euler(R), CAM, cfg.flow)[0]


def cover_ratio(prev: np.ndarray, cur: np.ndarray, box: tuple[float, float, float, float],
                depth: float, R: np.ndarray, t_m: np.ndarray, cfg: Config) -> tuple[float, int]:
    """The cover ratio of ``box`` (its probe grid) for an object at ``depth`` m."""
    pts = probe_points(box, CAM.width, CAM.height)
    return cover_from_flow(CoastProbe(pts, depth, R, t_m), measured(prev, cur, pts, R, cfg), CAM)


def course_points(prev: np.ndarray, cur: np.ndarray, box: tuple[float, float, float, float],
                  depth: float, R: np.ndarray, t_m: np.ndarray, cfg: Config,
                  low_ratio: float = 0.25) -> tuple[float, float]:
    """The head-band count and column of ``box`` (its band grid) for an object at ``depth`` m."""
    pts = band_points(box, CAM.width, CAM.height)
    return course_count(CoastProbe(pts, depth, R, t_m), measured(prev, cur, pts, R, cfg), CAM,
                        low_ratio)


@pytest.mark.parametrize(("wall_m", "object_m"), [(10.0, 15.0), (10.0, 10.0), (15.0, 10.0)])
def test_cover_ratio_is_the_depth_ratio(default_config: Config, wall_m: float,
                                        object_m: float) -> None:
    """What is in the box at ``wall_m`` against an object expected at ``object_m``: the
    ratio is about ``object_m / wall_m`` (> 1: something nearer covers the object)."""
    prev, cur = wall_pair(wall_m)
    ratio, n = cover_ratio(prev, cur, BOX, object_m, np.eye(3), T_M, default_config)
    expected = (object_m + STEP_M) / (wall_m + STEP_M)
    assert n >= 20
    assert ratio == pytest.approx(expected, rel=0.08)


def test_rotation_is_removed_before_the_ratio(default_config: Config) -> None:
    """A yaw between the frames shifts the whole image; with that rotation given, the ratio
    is unchanged; with it ignored, it is wrong."""
    prev, cur = wall_pair(10.0)
    yaw = math.radians(0.3)
    R = np.array([[math.cos(yaw), 0.0, math.sin(yaw)], [0.0, 1.0, 0.0],
                  [-math.sin(yaw), 0.0, math.cos(yaw)]])
    shift = CAM.fx * math.tan(yaw)   # a point at the centre moves by f tan(yaw) to the right
    cur = cv2.warpAffine(cur, np.array([[1.0, 0.0, shift], [0.0, 1.0, 0.0]]), (CAM.width, CAM.height),
                         borderMode=cv2.BORDER_REFLECT)
    right, _ = cover_ratio(prev, cur, BOX, 15.0, R, T_M, default_config)
    wrong, _ = cover_ratio(prev, cur, BOX, 15.0, np.eye(3), T_M, default_config)
    assert right == pytest.approx(15.4 / 10.4, rel=0.1)
    assert abs(wrong - 15.4 / 10.4) > 0.3


def test_flat_or_unmeasurable_boxes_give_no_ratio(default_config: Config) -> None:
    """A flat image (nothing to track), a box outside the image, an unknown translation and a
    box at the epipole (no static flow to compare with) give NaN and 0 points, no exception."""
    flat = np.full((CAM.height, CAM.width), 90, np.uint8)
    assert cover_ratio(flat, flat, BOX, 10.0, np.eye(3), T_M, default_config)[1] == 0
    prev, cur = wall_pair(10.0)
    out = (700.0, 500.0, 760.0, 600.0)
    assert cover_ratio(prev, cur, out, 10.0, np.eye(3), T_M, default_config)[1] == 0
    nan_t = np.full(3, np.nan)
    assert cover_ratio(prev, cur, BOX, 10.0, np.eye(3), nan_t, default_config)[1] == 0
    centre = (317.0, 237.0, 322.0, 242.0)
    ratio, n = cover_ratio(prev, cur, centre, 10.0, np.eye(3), T_M, default_config)
    assert n == 0 and math.isnan(ratio)


def test_probe_box_grows_a_shrunken_box_to_a_body() -> None:
    """A 3 x 6 px remnant at 20 m becomes at least 0.6 x 1.2 m (21 x 42 px at f = 700), bottom
    kept; a box already larger stays; the grid covers its lower 60 % inside the image."""
    u0, v0, u1, v1 = probe_box(400.0, 300.0, (3.0, 6.0), 20.0, CAM)
    assert (u1 - u0, v1 - v0, v1) == pytest.approx((21.0, 42.0, 300.0))
    assert probe_box(400.0, 300.0, (50.0, 80.0), 20.0, CAM) == pytest.approx((375.0, 220.0, 425.0, 300.0))
    pts = probe_points((100.0, 100.0, 200.0, 300.0), CAM.width, CAM.height)
    assert len(pts) == 36 and pts[:, 1].min() > 180.0 and pts[:, 1].max() < 300.0
    assert len(probe_points((620.0, 100.0, 700.0, 300.0), CAM.width, CAM.height)) < 36


def _lost(cover: tuple[float, ...]) -> LostTrack:
    return LostTrack(id=1, cues=TrackCues(), cover=cover)


def test_a_lost_track_counts_as_hidden_on_the_median_of_its_last_ratios() -> None:
    assert (lost_tracks.COVER_RATIO, lost_tracks.COVER_FRAMES) == (1.15, 5)
    assert _lost((1.3, 1.2, 0.4, 1.25, 1.4)).covered()         # one bad frame does not decide
    assert not _lost((0.8, 0.7, 1.6, 0.9, 0.75)).covered()     # nor does one high one
    assert not _lost((1.3, 1.3, 1.3, 0.7, 0.8, 0.7, 0.6, 0.9)).covered()  # only the last 5 count
    assert _lost((math.nan, 1.3, math.nan, 1.2)).covered()     # unmeasured frames are left out
    assert not _lost((math.nan, math.nan)).covered()           # nothing measured: not hidden
    assert not _lost(()).covered()


def coasted_at(u: float, v: float) -> tuple[ImageTrack, EgoMotion, SensorSample]:
    """A coasted 4 x 8 px image track centred at (u, v), the camera driving straight ahead
    (epipole at the principal point) at ``STEP_M`` per frame, and its CAN sample."""
    x = np.zeros((2, 3))
    x[0, 0], x[1, 0] = u, v
    tr = ImageTrack(uid=1, id=1, x=x, P=np.zeros((2, 3, 3)), size=(4.0, 8.0), age=10, misses=0,
                    cluster=None, probability=0.6)
    ego = EgoMotion(rotation=np.zeros(3), translation_dir=np.array([0.0, 0.0, -1.0]),
                    epipole_px=(CAM.cx, CAM.cy), prior_rotation=np.zeros(3),
                    prior_translation_dir=np.array([0.0, 0.0, -1.0]), prior_epipole_px=None,
                    inliers=100, confident=True)
    return tr, ego, SensorSample(t=0.0, speed_m_s=STEP_M * 30.0, yaw_rate_rad_s=0.0)


def test_coasted_cover_needs_images_and_motion(default_config: Config) -> None:
    """From a coasted image track and its foot point: the ratio with the flow measured at its
    probe, NaN without a measured flow; no probe at a standstill."""
    prev, cur = wall_pair(10.0)
    tr, ego, sensors = coasted_at(445.0, 330.0)
    foot = np.array([1.0, 1.2, 15.0])
    p = cover_probe(tr, foot, ego, sensors, 1.0 / 30.0, CAM)
    assert p is not None and p.depth_m == 15.0
    ratio, _ = cover_from_flow(p, measured(prev, cur, p.points, p.R, default_config), CAM)
    assert ratio == pytest.approx(15.4 / 10.4, rel=0.1)
    assert math.isnan(cover_from_flow(p, None, CAM)[0])
    assert cover_probe(tr, foot, replace(ego, standstill=True), sensors, 1 / 30, CAM) is None


HEAD = np.array([445.0, 280.0])   # px, a head's centre in the previous frame
OBJECT_M = 10.0                   # m, the object's depth now


def magnify(point: np.ndarray, depth_cur: float) -> np.ndarray:
    """Where a static point at ``depth_cur`` m now, seen at ``point`` before, is now."""
    s = (depth_cur + STEP_M) / depth_cur
    c = np.array([CAM.cx, CAM.cy])
    out: np.ndarray = c + s * (point - c)
    return out


def head_pair(head_now: np.ndarray | None, wall_m: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    """The wall at ``wall_m`` behind a bright 5 x 5 px head at ``HEAD`` before and at
    ``head_now`` now (None: no head)."""
    prev, cur = wall_pair(wall_m)
    if head_now is not None:
        for img, p in ((prev, HEAD), (cur, head_now)):
            u, v = np.round(p).astype(int)
            img[v - 2:v + 3, u - 2:u + 3] = 250
    return prev, cur


BAND = (425.0, 270.0, 465.0, 290.0)


def _count(prev: np.ndarray, cur: np.ndarray, cfg: Config) -> float:
    return course_points(prev, cur, BAND, OBJECT_M, np.eye(3), T_M, cfg)[0]


def test_course_points_see_a_head_that_keeps_its_bearing(default_config: Config) -> None:
    """A head 10 m ahead in front of a wall 20 m ahead. Keeping its bearing (a collision
    course), the points whose window holds it have a flow ratio near 0: several count. Moving
    like a static point at its depth (it stopped), none does, nor does the wall alone (its
    ratio is 10.4 / 20.4, about 0.5)."""
    walking = _count(*head_pair(HEAD), default_config)
    stopped = _count(*head_pair(magnify(HEAD, OBJECT_M)), default_config)
    wall = _count(*head_pair(None), default_config)
    need = lost_tracks.COURSE_POINTS
    assert walking >= 3 * need
    assert stopped < need and wall < need
    # the points that see it lie around its column
    column = course_points(*head_pair(HEAD), BAND, OBJECT_M, np.eye(3), T_M, default_config)[1]
    assert column == pytest.approx(HEAD[0], abs=2.0)
    # the band's grid: about every HEAD_GRID_PX (1.5 px), inside the image
    pts = band_points(BAND, CAM.width, CAM.height)
    assert len(pts) == 26 * 13 and np.all(np.diff(np.unique(pts[:, 0])) < 1.7)
    assert len(band_points((600.0, 270.0, 700.0, 290.0), CAM.width, CAM.height)) < 26 * 13


def test_unmeasurable_band_gives_no_count(default_config: Config) -> None:
    flat = np.full((CAM.height, CAM.width), 90, np.uint8)
    assert math.isnan(_count(flat, flat, default_config))
    prev, cur = head_pair(HEAD)
    out = (700.0, 500.0, 760.0, 600.0)
    assert all(math.isnan(v) for v in course_points(prev, cur, out, OBJECT_M, np.eye(3), T_M,
                                                    default_config))


def test_head_band_lies_at_the_top_of_an_object_of_its_height() -> None:
    """A 1.75 m pedestrian standing at row 400, 20 m away (35 px/m at f = 700): its top at row
    338.75; the band from 0.15 m above to 0.5 m below it, 1.2 m (42 px) wide at least."""
    u0, v0, u1, v1 = head_band(300.0, 400.0, 10.0, 1.75, 20.0, CAM)
    assert (u0, u1) == pytest.approx((279.0, 321.0))
    assert (v0, v1) == pytest.approx((338.75 - 5.25, 338.75 + 17.5))
    assert head_band(300.0, 400.0, 60.0, 1.75, 20.0, CAM)[0] == pytest.approx(270.0)


def test_coasted_course_from_a_coasted_track(default_config: Config) -> None:
    """From a coasted image track (bottom at row 330, 10 m: a 1.0 m object's top at row 260,
    the head band 255-295) and its foot point: the count with the flow at its probe; NaN
    without a measured flow; no probe at a standstill or without a known height."""
    tr, ego, sensors = coasted_at(445.0, 326.0)
    foot = np.array([0.5, 1.2, OBJECT_M])
    p = course_probe(tr, foot, 1.0, ego, sensors, 1.0 / 30.0, CAM)
    assert p is not None

    def count(pair: tuple[np.ndarray, np.ndarray]) -> tuple[float, float]:
        return course_count(p, measured(*pair, p.points, p.R, default_config), CAM)

    n, column = count(head_pair(HEAD))
    assert n >= 9 and column == pytest.approx(HEAD[0], abs=2.0)
    assert count(head_pair(magnify(HEAD, OBJECT_M)))[0] < 3
    assert math.isnan(course_count(p, None, CAM)[0])
    assert course_probe(tr, foot, 0.0, ego, sensors, 1 / 30, CAM) is None
    assert course_probe(tr, foot, 1.0, replace(ego, standstill=True), sensors, 1 / 30, CAM) is None


# stop-behind seed 2's head band: walking on hidden, then slowing down (a few points background)
STOP_BEHIND_WALKED = (17.0, 44.0, 44.0, 24.0, 12.0, 27.0, 36.0, 73.0, 50.0, 43.0, 56.0, 34.0, 29.0)
STOP_BEHIND_SLOWED = (1.0, 3.0, 2.0, 6.0, 4.0, 4.0, 0.0, 15.0, 6.0)


def _course(counts: tuple[float, ...]) -> LostTrack:
    lt = LostTrack(id=1, cues=TrackCues())
    for c in counts:
        lt = lt.with_course(c)
    return lt


def test_a_lost_track_is_off_course_for_good_on_the_median_of_its_counts(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Counts of a head band (need 3, median over 5 frames): walking on (the median stays 3
    or more, one empty frame or a short run of them does not decide), then stopped (the
    median falls below 3): off course, and it stays so when the band later catches something
    far that keeps its bearing. A head never seen on course (an occluder taller than the
    object) does not make it off course."""
    assert (lost_tracks.COVER_FRAMES, lost_tracks.COURSE_POINTS) == (5, 3)
    monkeypatch.setattr(lost_tracks, "COURSE_FRACTION", 0.0)
    walking = (17.0, 44.0, 0.0, 12.0, 6.0, 3.0, 0.0, 4.0)
    assert not _course(walking).off_course and _course(walking).seen_on_course
    stopped = _course((*walking, 0.0, 1.0, 5.0, 0.0))
    assert stopped.off_course
    assert _course((*walking, 0.0, 1.0, 5.0, 0.0, 18.0, 23.0, 16.0, 30.0, 40.0)).off_course
    assert len(stopped.course) == 5                                   # only the last 5 are kept
    assert not _course((20.0, 30.0, 0.0, 1.0, math.nan, 0.0)).off_course  # 4 measured: too few to say
    assert not _course((math.nan,) * 8).off_course               # never measured: as before
    never = _course((0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0))        # the head never showed
    assert not never.off_course and not never.seen_on_course


def test_off_course_also_below_a_fraction_of_the_highest_count(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Stop-behind seed 2 with the head's bearing fed to the coasted state: 30-70 points while
    the pedestrian walked on hidden, then 1-8 once it slowed down, a few of them background.
    Against 3 points alone it would stay on course; against a quarter of its highest median
    (50: 12.5) it is off course at the third frame of the slow-down."""
    walked, slowed = STOP_BEHIND_WALKED, STOP_BEHIND_SLOWED
    assert lost_tracks.COURSE_FRACTION == 0.25
    assert not _course((*walked, *slowed[:2])).off_course
    assert _course((*walked, *slowed[:3])).off_course
    assert _course((*walked, *slowed[:3])).course_peak == 50.0
    monkeypatch.setattr(lost_tracks, "COURSE_FRACTION", 0.0)
    assert not _course((*walked, *slowed)).off_course


def test_a_head_counted_at_the_backgrounds_level_is_never_seen_and_never_lost(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Nearside seed 2, the pedestrian 27 m away: its head band counted 4, 5, 6, 2, 2, 6, 4, 1
    (background in the band alone counts 3-6). Seen on course at a median of 4, it was off
    course at the first median of 2 and its correct coasted warning (TTC 2.6 s, truth 2.67 s)
    would be dropped. With ``COURSE_SEEN_POINTS`` 8 such counts never make it seen, so it
    coasts on; a head counted 12-73 (stop-behind seed 2 walking hidden) is seen, and lost when
    the count falls to the background's."""
    assert lost_tracks.COURSE_SEEN_POINTS == 8
    far_head = (4.0, 5.0, 6.0, 2.0, 2.0, 6.0, 4.0, 1.0)
    lt = _course(far_head)
    assert not lt.seen_on_course and not lt.off_course
    assert _course(STOP_BEHIND_WALKED).seen_on_course
    assert _course((*STOP_BEHIND_WALKED, *STOP_BEHIND_SLOWED[:3])).off_course
    monkeypatch.setattr(lost_tracks, "COURSE_SEEN_POINTS", 0)
    assert _course(far_head).off_course                          # seen at the background's level
