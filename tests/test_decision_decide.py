"""The decision stage end to end on constructed particle sets with exact geometry.

A box-shaped mover and a static road/facade scene are projected through the
camera on a moving ego vehicle; particles on the mover carry high weights and
exact flows (plus noise), particles on the static scene low weights. This checks
the whole decision chain (map, clusters, tracks, 3-D state, warnings) on exact
constant-velocity collision courses and near misses, without the vision core.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from appliance.config import Config
from appliance.decision.decide import DecisionOutput, init_decision_state
from appliance.messages import EgoMotion, ParticleSet, SensorSample
from appliance.pipeline import decision_step
from appliance.vision.geometry import PinholeCamera, vehicle_from_camera_rotation

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
FPS = 30.0


@dataclass(frozen=True)
class Step:
    frame: int
    t: float
    particles: ParticleSet
    ego: EgoMotion
    sensors: SensorSample
    rel: np.ndarray  # object centre relative to the ego origin (vehicle frame), m


def project(cfg: Config, P: np.ndarray, ego_x: float) -> np.ndarray:
    m = cfg.mount
    Rvc = vehicle_from_camera_rotation(m.pitch_rad, 0.0, 0.0)
    return CAM.project((P - np.array([m.x_m + ego_x, m.y_m, m.z_m])) @ Rvc)


def inside(uv: np.ndarray) -> np.ndarray:
    return (np.all(np.isfinite(uv), axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] < CAM.width)
            & (uv[:, 1] >= 0) & (uv[:, 1] < CAM.height))


def scene(cfg: Config, obj0: tuple[float, float] | None, vel: tuple[float, float], speed: float,
          n_frames: int, size: tuple[float, float, float] = (0.4, 0.6, 1.7), seed: int = 0,
          hidden: frozenset[int] = frozenset(), n_obj: int = 200) -> Iterator[Step]:
    """World = vehicle frame at t = 0; the ego drives straight along x at ``speed``."""
    rng = np.random.default_rng(seed)
    L, W, H = size
    local = np.column_stack([rng.uniform(-L / 2, L / 2, 400), rng.uniform(-W / 2, W / 2, 400),
                             rng.uniform(0.0, H, 400)])
    statics = np.vstack([
        np.column_stack([rng.uniform(5, 80, 2000), rng.uniform(-6, 6, 2000), np.zeros(2000)]),
        np.column_stack([rng.uniform(5, 80, 1000), rng.choice([-7.0, 7.0], 1000),
                         rng.uniform(0, 6, 1000)]),
    ])
    dt = 1.0 / FPS
    still = np.zeros(3)
    for i in range(1, n_frames):
        t = i * dt
        pos, flow, w = [], [], []
        if obj0 is not None and i not in hidden:
            o_t = np.array([*obj0, 0.0]) + np.array([*vel, 0.0]) * t
            o_p = o_t - np.array([*vel, 0.0]) * dt
            cur = project(cfg, local + o_t, speed * t)
            prev = project(cfg, local + o_p, speed * (t - dt))
            ok = np.flatnonzero(inside(cur) & inside(prev))
            sel = rng.choice(ok, min(n_obj, len(ok)), replace=False) if len(ok) else ok
            # like Lucas-Kanade, particles up to half a window (5.5 px) off the object still
            # measure its motion: a halo around the object
            halo = rng.uniform(-5.0, 5.0, (len(sel), 2))
            pos.append(cur[sel] + halo)
            flow.append(cur[sel] - prev[sel])
            w.append(np.clip(rng.normal(0.95, 0.05, len(sel)), 0, 1))
        cur = project(cfg, statics, speed * t)
        prev = project(cfg, statics, speed * (t - dt))
        sel = rng.choice(np.flatnonzero(inside(cur) & inside(prev)), 150, replace=False)
        pos.append(cur[sel])
        flow.append(cur[sel] - prev[sel])
        w.append(np.clip(rng.normal(0.1, 0.05, len(sel)), 0, 1))
        p = np.vstack(pos)
        f = np.vstack(flow) + rng.normal(0, 0.05, p.shape)
        parts = ParticleSet(p, f, np.concatenate(w), np.ones(len(p), dtype=bool), 9, 0.5)
        fwd = np.array([0.0, 0.0, -1.0]) if speed > 0 else np.zeros(3)
        ego = EgoMotion(still, fwd, (CAM.cx, CAM.cy), still, fwd, (CAM.cx, CAM.cy), 150, True,
                        standstill=speed <= 0)
        rel = (np.array(obj0) + np.array(vel) * t - np.array([speed * t, 0.0])
               if obj0 is not None else np.zeros(2))
        yield Step(i, t, parts, ego, SensorSample(t, speed, 0.0), rel)


def run(cfg: Config, steps: Iterator[Step]) -> list[tuple[Step, DecisionOutput]]:
    state = init_decision_state(cfg, CAM)
    out = []
    for s in steps:
        state, o = decision_step(state, s.frame, s.t, s.particles, s.ego, s.sensors, cfg, CAM)
        out.append((s, o))
    return out


def crossing(speed: float, walk: float, t_collision: float, y_hit: float
             ) -> tuple[tuple[float, float], tuple[float, float]]:
    """Start and velocity of a pedestrian crossing from the right into the bumper at y_hit."""
    front = 3.9 + 0.2  # bumper + the pedestrian's half depth
    return (front + speed * t_collision, y_hit - walk * t_collision), (0.0, walk)


def test_collision_course_warns_early_with_accurate_ttc(default_config: Config) -> None:
    cfg = default_config
    # Euro NCAP "adult nearside" like: 9.2 m/s, 1.4 m/s, impact at 25 % of the width
    obj0, vel = crossing(9.2, 1.4, 4.0, -0.45)
    res = run(cfg, scene(cfg, obj0, vel, 9.2, 115))
    level2 = [s.t for s, o in res for e in o.warnings if e.level == 2]
    assert level2, "no level-2 warning on a collision course"
    lead = 4.0 - level2[0]
    assert 1.5 <= lead <= 2.4
    # TTC and distance over the last 3 s before contact
    ttc_err, d_err = [], []
    for s, o in res:
        tt = 4.0 - s.t
        if not 0.3 < tt <= 3.0 or len(o.tracks) != 1:
            continue
        tr = o.tracks[0]
        if tr.ttc_s is not None:
            ttc_err.append(abs(tr.ttc_s - tt) / tt)
        d_true = np.hypot(max(s.rel[0] - 0.2 - 3.9, 0.0), max(abs(s.rel[1]) - 0.9, 0.0))
        if tr.distance_m is not None:
            d_err.append(abs(tr.distance_m - d_true) / d_true)
    assert len(ttc_err) > 50 and np.median(ttc_err) < 0.1
    assert len(d_err) > 50 and np.median(d_err) < 0.15  # the target
    # one track with one stable id, levels only go up
    ids = {tr.id for _, o in res for tr in o.tracks}
    assert ids == {1}
    assert [e.level for _, o in res for e in o.warnings] == [1, 2]


@pytest.mark.parametrize("walk", [3.0, 0.6])
def test_near_miss_gives_no_level_2(default_config: Config, walk: float) -> None:
    """The pedestrian clears the corridor before the car arrives (3 m/s) or stops short of it."""
    cfg = default_config
    if walk == 3.0:  # crosses: at the car's arrival it is 1.5 m beyond the left edge
        obj0, vel = crossing(9.2, walk, 3.5, 0.9 + 0.3 + 1.5)
    else:  # walks slowly from far right; at the car's arrival it is still 2 m right of it
        obj0, vel = crossing(9.2, walk, 3.5, -0.9 - 2.0)
    res = run(cfg, scene(cfg, obj0, vel, 9.2, 100))
    assert [e for _, o in res for e in o.warnings if e.level == 2] == []
    assert any(o.tracks for _, o in res)  # it was tracked, just not a threat


def test_static_scene_and_empty_frames_give_nothing(default_config: Config) -> None:
    cfg = default_config
    res = run(cfg, scene(cfg, None, (0.0, 0.0), 12.0, 60))
    assert all(o.tracks == () and o.warnings == () and o.warning_level == 0 for _, o in res)
    state = init_decision_state(cfg, CAM)
    empty = ParticleSet(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=bool),
                        9, 0.5)
    ego = EgoMotion(np.zeros(3), np.zeros(3), None, np.zeros(3), np.zeros(3), None, 0, False)
    for k in range(5):
        state, o = decision_step(state, k, k / FPS, empty, ego,
                                 SensorSample(k / FPS, float("nan"), 0.0, can_valid=False), cfg, CAM)
        assert o.tracks == () and o.warning_level == 0 and o.warning_track is None
        assert o.prob_map.p.shape == (120, 160)


def test_standstill_object_walking_at_the_car(default_config: Config) -> None:
    cfg = default_config
    # ego stopped; a pedestrian 12 m ahead walks straight at the bumper at 1.5 m/s
    res = run(cfg, scene(cfg, (3.9 + 0.2 + 12.0, -0.3), (-1.5, 0.0), 0.0, 120))
    s, o = res[90]
    assert len(o.tracks) == 1 and o.tracks[0].ttc_s is not None
    true_ttc = 8.0 - s.t
    assert o.tracks[0].ttc_s == pytest.approx(true_ttc, rel=0.15)


def test_occlusion_keeps_the_track_id(default_config: Config) -> None:
    cfg = default_config
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    res = run(cfg, scene(cfg, obj0, vel, 8.0, 60, hidden=frozenset({30, 31})))
    ids = [tuple(tr.id for tr in o.tracks) for _, o in res]
    assert ids[25] == (1,) and ids[30] == (1,) and ids[31] == (1,) and ids[40] == (1,)


def test_box_touching_the_border_falls_back_to_the_scale_cue(default_config: Config) -> None:
    """Standstill; a pedestrian walks at the car until its feet leave the bottom of the image
    (1.8 m before the bumper): the ground contact is unknown, the 3-D state coasts for
    coast_s, then the distance is null while the scale cue (referred to the bumper with the
    depth it carried on) still gives the TTC, and the level-2 warning stays on."""
    # (this synthetic cloud is sparser than the vision's, so its eq. 20 probability is lower)
    cfg = default_config.with_overrides({"cue": {"ground": {"coast_s": 0.5}},
                                         "warning": {"min_probability": 0.4}})
    walk, start = 1.0, 6.0  # m/s, m ahead of the bumper
    res = run(cfg, scene(cfg, (3.9 + 0.2 + start, -0.2), (-walk, 0.0), 0.0, 160, n_obj=400))
    assert all(len(o.tracks) == 1 for s, o in res if s.t > 0.5)
    seen = [o.tracks[0].distance_m for s, o in res if 1.0 < s.t < 3.5]
    assert all(d is not None for d in seen)
    s, o = res[-1]
    tr = o.tracks[0]
    assert tr.bbox[3] >= CAM.height - 8  # cut off by the image border (less the halo)
    assert all(0 <= r.bbox[0] <= r.bbox[2] <= CAM.width and 0 <= r.bbox[1] <= r.bbox[3]
               <= CAM.height for _, o in res for r in o.tracks)  # boxes stay in the image
    assert tr.distance_m is None  # ground contact unknown: say so
    true_ttc = start / walk - s.t
    assert tr.ttc_s is not None and tr.ttc_s == pytest.approx(true_ttc, abs=0.25)
    assert [e.level for _, o in res for e in o.warnings] == [1, 2]
    assert o.warning_level == 2 and o.warning_track is not None


def test_replay_is_deterministic(default_config: Config) -> None:
    cfg = default_config
    obj0, vel = crossing(9.2, 1.4, 3.0, 0.0)
    a = run(cfg, scene(cfg, obj0, vel, 9.2, 40, seed=5))
    b = run(cfg, scene(cfg, obj0, vel, 9.2, 40, seed=5))
    assert [o.tracks for _, o in a] == [o.tracks for _, o in b]
    assert [o.warnings for _, o in a] == [o.warnings for _, o in b]


def test_long_occlusion_reacquires_the_lost_track(default_config: Config) -> None:
    """Hidden for 1 s (a parked car): the image track is deleted; with ``hidden.keep_s`` the
    coasted 3-D state takes the reappearing object back under its id, moving at once."""
    hidden = frozenset(range(40, 70))
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    no = default_config.with_overrides({"hidden": {"keep_s": 0.0, "warn_s": 0.0}})
    off = run(no, scene(no, obj0, vel, 8.0, 90, hidden=hidden))
    cfg = default_config.with_overrides({"hidden": {"keep_s": 2.0}})
    on = run(cfg, scene(cfg, obj0, vel, 8.0, 90, hidden=hidden))
    before = {tr.id for tr in on[38][1].tracks}
    assert len(before) == 1
    assert not off[60][1].tracks and not on[60][1].tracks  # the image track is gone
    ids_on = {tr.id for _, o in on[70:] for tr in o.tracks}
    ids_off = {tr.id for _, o in off[70:] for tr in o.tracks}
    assert ids_on == before
    assert ids_off and not ids_off & before
    # the reacquired track has its TTC as soon as it is reported again
    first = next(o for _, o in on[70:] if o.tracks)
    assert first.tracks[0].ttc_s is not None


def test_reacquisition_gate_rejects_a_far_object(default_config: Config,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The gate in metres: an object reappearing further than ``REACQUIRE_GATE_M`` from the
    coasted position (here by the coasting error alone) starts a new track."""
    hidden = frozenset(range(40, 70))
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    monkeypatch.setattr("appliance.decision.lost_tracks.REACQUIRE_GATE_M", 0.5)
    cfg = default_config.with_overrides({"hidden": {"keep_s": 2.0}})
    res = run(cfg, scene(cfg, obj0, vel, 8.0, 90, hidden=hidden))
    before = {tr.id for tr in res[38][1].tracks}
    later = {tr.id for _, o in res[75:] for tr in o.tracks}
    assert later and not later & before


def test_only_tracks_that_moved_are_reacquired(default_config: Config) -> None:
    """Hidden before its 3-D state could show motion (fewer than ``cue.motion.min_frames``
    contacts): it comes back as a new track; hidden later, it keeps its id."""
    cfg = default_config.with_overrides({"hidden": {"keep_s": 2.0},
                                         "cue": {"motion": {"min_frames": 10}}})
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    early = run(cfg, scene(cfg, obj0, vel, 8.0, 60, hidden=frozenset(range(10, 40))))
    before = {tr.id for tr in early[8][1].tracks}
    assert len(before) == 1
    after = {tr.id for _, o in early[45:] for tr in o.tracks}
    assert after and not after & before


def test_a_box_cut_by_the_side_border_takes_its_bearing_at_its_inner_edge(
        default_config: Config) -> None:
    """The centre of a box cut by the left border stays near the border while the object
    leaves the image (a constant bearing: a collision course to the monocular test); the
    bearing is taken at the inner edge, which moves with the object. A box clear of the
    borders keeps its track's centre."""
    from appliance.decision.clustering import Cluster
    from appliance.decision.frame import BORDER_MARGIN_PX, border_sides
    from appliance.decision.frame import bearing_pixel as take_bearing_pixel
    from appliance.decision.tracking import ImageTrack

    def cluster(u0: float, u1: float) -> Cluster:
        pos = np.column_stack([np.linspace(u0, u1, 40), np.full(40, 260.0)])
        return Cluster(bbox=(u0, 240.0, u1, 280.0), region_bbox=(u0, 240.0, u1, 280.0), n=40,
                       foot_v=280.0, mean_flow=(0.0, 0.0), mean_probability=0.9, positions=pos,
                       flows=np.zeros((40, 2)), s=np.ones(40), weights=np.ones(40))

    def track(c: Cluster) -> ImageTrack:
        x = np.array([[c.center[0], 0.0, 0.0], [c.center[1], 0.0, 0.0]])
        return ImageTrack(uid=1, id=1, x=x, P=np.ones((2, 3, 3)), size=(60.0, 40.0), age=10,
                          misses=0, cluster=c, probability=0.9)

    def bearing_pixel(tr: ImageTrack, c: Cluster | None) -> tuple[tuple[float, float], str]:
        sides = (False, False, False) if c is None else border_sides(c, CAM, BORDER_MARGIN_PX,
                                                                     4.5)
        return take_bearing_pixel(tr, c, sides)

    cut = cluster(2.0, 60.0)
    assert bearing_pixel(track(cut), cut) == ((60.0, 260.0), "left")
    right = cluster(580.0, 639.0)
    assert bearing_pixel(track(right), right) == ((580.0, 260.0), "right")
    clear = cluster(200.0, 260.0)
    assert bearing_pixel(track(clear), clear) == ((230.0, 260.0), "centre")
    assert bearing_pixel(track(cut), None)[1] == "centre"
