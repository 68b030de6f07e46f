"""Warning levels: thresholds, persistence, hysteresis, hold; no flicker, no single-frame warning."""

from __future__ import annotations

import numpy as np
import pytest

from appliance.config import Config, WarningConfig
from appliance.decision.assess import TrackThreat
from appliance.decision.warnings import (
    FAST_MOVER_M_S,
    GROWTH_SHARE,
    GROWTH_SIGMAS,
    indication,
    HIDDEN_MIN_PROBABILITY,
    ONLY_MAY_STAND,
    WarningState,
    pool_covered,
    warning_step,
)
from appliance.messages import TrackReport, WarningEvent

FPS = 30.0


def threat(tid: int, ttc: float | None, on_course: bool = True, wide: bool | None = None
           ) -> TrackThreat:
    rep = TrackReport(id=tid, bbox=(300.0, 200.0, 340.0, 280.0), probability=0.8, flow=(0.0, 0.0),
                      ttc_s=ttc, distance_m=None if ttc is None else 10.0 * ttc,
                      bearing_rad=-0.1)
    return TrackThreat(report=rep, on_course=on_course,
                       on_course_wide=on_course if wide is None else wide)


def run(cfg: WarningConfig, frames: list[tuple[TrackThreat, ...]], hidden_max_level: int = 2
        ) -> tuple[list[int], list[WarningEvent]]:
    state = WarningState()
    levels: list[int] = []
    events: list[WarningEvent] = []
    for k, threats in enumerate(frames):
        state, ev, _, _ = warning_step(state, threats, k / FPS, k, cfg,
                                       hidden_max_level=hidden_max_level)
        levels.append(state.level)
        events.extend(ev)
    return levels, events


def test_no_flicker_on_a_ttc_oscillating_around_the_threshold(default_config: Config) -> None:
    cfg = default_config.warning  # 3.0 / 2.0 s, hysteresis 0.3 s, persistence 3, hold 0.5 s
    # a noisy approach (+-0.1 s) down to 1.7 s, then a TTC jittering +-0.2 s around the 2.0 s
    # threshold for two seconds (the object slowed down)
    ttcs = [t + 0.1 * (-1) ** k for k, t in enumerate(np.linspace(3.5, 1.7, 40))]
    ttcs += [2.0 + 0.2 * (-1) ** k for k in range(60)]
    levels, events = run(cfg, [(threat(1, t),) for t in ttcs])
    assert [e.level for e in events] == [1, 2]  # once up to caution, once up to warning
    assert levels[-60:].count(2) >= 55  # held through the jitter
    # without hysteresis, persistence and hold, the same input flickers
    bare = default_config.with_overrides({"warning": {
        "hysteresis_s": 0.0, "min_persistence_frames": 1, "hold_s": 0.0}}).warning
    _, bare_events = run(bare, [(threat(1, t),) for t in ttcs])
    assert len(bare_events) > 20


def test_no_single_frame_warning(default_config: Config) -> None:
    cfg = default_config.warning
    frames = [(threat(1, None),)] * 10 + [(threat(1, 0.8),)] + [(threat(1, None),)] * 10
    frames += [(threat(1, 0.8),)] * 2 + [(threat(1, 5.0),)] * 10
    levels, events = run(cfg, frames)
    assert events == [] and max(levels) == 0
    # three consecutive frames: issued on the third
    levels, events = run(cfg, [(threat(1, None),)] * 5 + [(threat(1, 0.8),)] * 3)
    assert [(e.level, e.frame) for e in events] == [(2, 7)]


def test_path_outside_the_corridor_gives_no_warning(default_config: Config) -> None:
    cfg = default_config.warning
    levels, events = run(cfg, [(threat(1, 1.0, on_course=False),)] * 20)
    assert events == [] and max(levels) == 0


def test_clears_after_hysteresis_and_hold_with_one_event(default_config: Config) -> None:
    cfg = default_config.warning
    frames = [(threat(1, 1.5),)] * 10 + [(threat(1, 2.2),)] * 10 + [(threat(1, 4.0),)] * 30
    levels, events = run(cfg, frames)
    # 2.2 s is within the 0.3 s hysteresis of the 2.0 s threshold: still level 2
    assert levels[10:20] == [2] * 10
    assert [e.level for e in events] == [2, 0]
    clear = events[-1]
    # the cleared event names the track and what it shows now
    assert clear.track == 1 and clear.frame == 20 and clear.ttc_s == 4.0


def test_lowered_only_after_the_hold_time(default_config: Config) -> None:
    cfg = default_config.with_overrides({"warning": {"hold_s": 1.0}}).warning
    frames = [(threat(1, 1.5),)] * 3 + [(threat(1, 6.0),)] * 60
    levels, events = run(cfg, frames)
    assert [e.level for e in events] == [2, 0]
    issued, cleared = events
    assert cleared.t - issued.t >= 1.0 - 1e-9
    assert cleared.t - issued.t < 1.0 + 2.0 / FPS
    # a TTC that becomes unknown (ground contact lost) holds until the contact is due
    frames = [(threat(1, 1.5),)] * 3 + [(threat(1, None),)] * 60
    _, events = run(cfg, frames)
    assert [e.level for e in events] == [2, 0]
    assert events[1].t == pytest.approx(2 / FPS + 1.5, abs=1.01 / FPS)


def test_lost_track_keeps_the_warning_until_its_contact_is_due(default_config: Config) -> None:
    cfg = default_config.warning  # hold 0.5 s
    frames: list[tuple[TrackThreat, ...]] = [(threat(7, 1.4 - k / FPS),) for k in range(6)]
    frames += [()] * 60  # the object went under the bonnet
    levels, events = run(cfg, frames)
    assert [e.level for e in events] == [2, 0]
    last_seen_t, last_ttc = 5 / FPS, 1.4 - 5 / FPS
    assert events[-1].t >= last_seen_t + last_ttc - 1e-9
    assert events[-1].t <= last_seen_t + last_ttc + 2.0 / FPS


def test_a_track_released_off_its_course_is_held_only_for_hold_s(default_config: Config) -> None:
    """A hidden pedestrian whose head was seen to stop (``released``) no longer keeps a level
    until its contact was due: the caution it raised ends after ``hold_s``. Not released, the
    same track's level is held to its contact time."""
    cfg = default_config.warning  # hold 0.5 s
    frames: list[tuple[TrackThreat, ...]] = [(threat(7, 2.8 - k / FPS),) for k in range(6)]
    frames += [()] * 90
    _, held = run(cfg, frames)
    state, events = WarningState(), []
    for k, threats in enumerate(frames):
        released = frozenset({7}) if k >= 6 else frozenset()
        state, ev, _, _ = warning_step(state, threats, k / FPS, k, cfg, released=released)
        events.extend(ev)
    assert [e.level for e in held] == [1, 0] and [e.level for e in events] == [1, 0]
    assert held[-1].t >= 5 / FPS + 2.8 - 5 / FPS - 1e-9  # held until the contact was due
    assert events[-1].t == pytest.approx(events[0].t + cfg.hold_s, abs=1.5 / FPS)


def test_highest_level_wins_and_events_name_the_track(default_config: Config) -> None:
    cfg = default_config.warning
    frames = [(threat(1, 2.8), threat(2, 1.5)) for _ in range(5)]
    levels, events = run(cfg, frames)
    assert [(e.level, e.track) for e in events] == [(2, 2)]
    e = events[0]
    assert e.bbox == (300.0, 200.0, 340.0, 280.0) and e.ttc_s == 1.5 and e.distance_m == 15.0
    assert e.bearing_rad == -0.1 and e.frame == 2 and e.t == 2 / FPS


def test_persistence_looks_ahead_by_its_window(default_config: Config) -> None:
    """A TTC falling at 1 s/s is issued when it reaches 2.0 s, not three frames later."""
    cfg = default_config.warning
    state = WarningState()
    issued = []
    for k in range(60):
        ttc = 2.5 - k / FPS
        state, ev, _, _ = warning_step(state, (threat(1, ttc),), k / FPS, k, cfg, frame_dt=1 / FPS)
        issued += [(e.level, ttc) for e in ev if e.level == 2]
    assert len(issued) == 1 and 2.0 - 1 / FPS < issued[0][1] <= 2.0 + 1e-9
    # without the look-ahead it comes (persistence - 1) frames late
    state, late = WarningState(), []
    for k in range(60):
        ttc = 2.5 - k / FPS
        state, ev, _, _ = warning_step(state, (threat(1, ttc),), k / FPS, k, cfg)
        late += [ttc for e in ev if e.level == 2]
    assert late[0] == pytest.approx(issued[0][1] - 2 / FPS)


def test_weak_or_static_tracks_raise_no_level(default_config: Config) -> None:
    from dataclasses import replace

    cfg = default_config.warning
    weak = TrackThreat(replace(threat(1, 1.0).report, probability=0.4), True, True)
    assert weak.report.probability < cfg.min_probability
    levels, events = run(cfg, [(weak,)] * 10)
    assert events == [] and max(levels) == 0
    still = TrackThreat(threat(1, 1.0).report, True, True, moving=False)
    levels, events = run(cfg, [(still,)] * 10)
    assert events == [] and max(levels) == 0
    # a hidden track assessed from its coasted state has its own bar, on its highest
    # probability while it was seen
    for p, issued in ((HIDDEN_MIN_PROBABILITY + 0.02, [2]), (HIDDEN_MIN_PROBABILITY - 0.02, [])):
        hidden = TrackThreat(replace(threat(1, 1.0).report, probability=p), True, True,
                             coasted=True)
        levels, events = run(cfg, [(hidden,)] * 10)
        assert [e.level for e in events] == issued
    flat = TrackThreat(threat(1, 1.0).report, True, True, height_m=0.1)   # a strip of road
    levels, events = run(cfg, [(flat,)] * 10)
    assert events == [] and max(levels) == 0
    # once raised, a warning is held for a track that stops (a pedestrian standing in the path)
    levels, events = run(cfg, [(threat(1, 1.0),)] * 4 + [(still,)] * 10)
    assert [e.level for e in events] == [2] and levels[-1] == 2


def test_a_fast_mover_needs_no_eq20_probability(default_config: Config) -> None:
    """A lead car at the epipole carries an eq. 20 probability of 0.5-0.7: a track moving over
    ground at ``FAST_MOVER_M_S`` or more raises its level anyway; a slow one with the same
    probability does not, nor a fast one that is not moving, off course or flat, or whose image
    grows as something standing there would."""
    from dataclasses import replace

    cfg = default_config.warning
    report = replace(threat(1, 1.0).report, probability=0.45)
    assert report.probability < cfg.min_probability
    fast = TrackThreat(report, True, True, speed_m_s=FAST_MOVER_M_S + 0.1)
    levels, events = run(cfg, [(fast,)] * 10)
    assert [e.level for e in events] == [2]
    slow = replace(fast, speed_m_s=FAST_MOVER_M_S - 0.1)
    levels, events = run(cfg, [(slow,)] * 10)
    assert events == [] and max(levels) == 0
    for other in (replace(fast, moving=False), replace(fast, on_course=False, on_course_wide=False),
                  replace(fast, height_m=0.1), replace(fast, grows_standing=True)):
        levels, events = run(cfg, [(other,)] * 10)
        assert events == [] and max(levels) == 0, other


def test_a_track_covering_another_passes_with_the_higher_probability(default_config: Config) -> None:
    """A near pedestrian split into a feet track (ground contact, TTC 1 s, eq. 20 probability
    0.4) and a head track above it (0.8, no contact): the feet track's outline covers the head
    track's centre, so it passes min_probability as one object; a track beside it does not."""
    from dataclasses import replace

    
    cfg = default_config.warning
    feet = TrackThreat(replace(threat(1, 1.0).report, bbox=(300.0, 120.0, 340.0, 280.0),
                               probability=0.4), True, True)
    head = TrackThreat(replace(threat(2, None).report, bbox=(305.0, 120.0, 338.0, 150.0),
                               probability=0.8), True, True)
    beside = TrackThreat(replace(threat(3, None).report, bbox=(350.0, 120.0, 380.0, 150.0),
                                 probability=0.9), True, True)
    assert run(cfg, [(feet, head)] * 10)[1] == []   # alone, the feet track is too weak
    pooled = pool_covered([feet, head])
    assert pooled[0].evidence == 0.8 and pooled[1].evidence is None
    assert pooled[0].report == feet.report          # tracks.jsonl keeps the track's own
    _, events = run(cfg, [tuple(pooled)] * 10)
    assert [(e.level, e.track) for e in events] == [(2, 1)]
    assert pool_covered([feet, beside])[0].evidence is None


def test_a_hidden_track_raises_at_most_hidden_max_level(default_config: Config) -> None:
    """``hidden.max_level`` 1: a coasted track only cautions; a level 2 issued while the track
    was seen is still held when it hides behind something."""
    from dataclasses import replace

    cfg = default_config.warning
    seen = threat(1, 1.0)
    hidden = TrackThreat(replace(seen.report, probability=0.6), True, True, coasted=True)
    assert [e.level for e in run(cfg, [(hidden,)] * 10)[1]] == [2]
    levels, events = run(cfg, [(hidden,)] * 10, hidden_max_level=1)
    assert [e.level for e in events] == [1] and levels[-1] == 1
    levels, events = run(cfg, [(seen,)] * 4 + [(hidden,)] * 10, hidden_max_level=1)
    assert [e.level for e in events] == [2] and levels[-1] == 2
    assert run(cfg, [(hidden,)] * 10, hidden_max_level=0)[1] == []


def test_what_only_may_stand_in_the_path_raises_a_caution(default_config: Config) -> None:
    """An obstacle whose evidence is short of the threshold (``suspected``) cautions, however
    near its contact; the same obstacle confirmed warns."""
    from dataclasses import replace

    cfg = default_config.warning
    confirmed = replace(threat(1, 1.0), moving=False, standing=True, closing=1.0)
    suspected = replace(confirmed, suspected=True)
    levels, events = run(cfg, [(suspected,)] * 10)
    assert [e.level for e in events] == [1] and levels[-1] == 1
    # and says why it is no warning, only where its time would warn
    assert reasons(cfg, [(suspected,)] * 10)[-1][1] == f"caution: {ONLY_MAY_STAND}"
    far = replace(suspected, report=replace(suspected.report, ttc_s=2.8))
    assert reasons(cfg, [(far,)] * 10)[-1][1] == "caution"
    levels, events = run(cfg, [(suspected,)] * 5 + [(confirmed,)] * 5)
    assert [e.level for e in events] == [1, 2] and levels[-1] == 2


def reasons(cfg: WarningConfig, frames: list[tuple[TrackThreat, ...]]) -> list[dict[int, str]]:
    state = WarningState()
    out = []
    for k, threats in enumerate(frames):
        state, _, _, why = warning_step(state, threats, k / FPS, k, cfg, frame_dt=1 / FPS)
        out.append(why)
    return out


def test_every_track_says_why_it_warns_or_not(default_config: Config) -> None:
    """The reason of each track (``tracks.jsonl``): the first check it fails, in the order a
    driver would ask (does it move, is it a road user, is it real, is it coming at us, how
    soon), else how far its indication has persisted, else its level."""
    from dataclasses import replace

    cfg = default_config.warning   # caution 3.0 s, warning 2.0 s, persistence 3, min p 0.5
    base = threat(1, 1.0)
    cases = {
        "not moving over ground": replace(base, moving=False),
        "box 0.10 m tall, below 0.30 m": replace(base, height_m=0.1),
        f"probability 0.40 below {cfg.min_probability:.2f}":
            replace(base, report=replace(base.report, probability=0.4)),
        "path misses corridor by 0.9 m": replace(base, on_course=False, on_course_wide=False,
                                                 miss_m=0.94),
        "path stays 14.0 m ahead in the corridor": replace(
            base, on_course=False, on_course_wide=False, miss_m=14.04, miss_ahead=True),
        "no time to collision": threat(1, None),
        "ttc 3.4 s above 3.1 s": threat(1, 3.4),   # the caution threshold looks 2 frames ahead
    }
    for why, th in cases.items():
        assert reasons(cfg, [(th,)] * 5)[-1] == {1: why}
    # persistence, then the level; a second track below the warned one says so
    got = reasons(cfg, [(threat(1, 1.0), threat(2, 2.5))] * 4)
    assert got[0] == {1: "caution indicated 1 of 3 frames", 2: "caution indicated 1 of 3 frames"}
    assert got[2] == {1: "warning", 2: "caution, track 1 warned"}
    # a hidden track's reason says it is hidden
    hidden = replace(threat(3, 1.0), coasted=True)
    assert reasons(cfg, [(hidden,)] * 3)[-1] == {3: "warning, hidden"}
    # the warned track whose TTC rises past the threshold is held for hold_s, and says what it
    # no longer meets
    got = reasons(cfg, [(threat(1, 1.0),)] * 3 + [(threat(1, 5.0),)] * 2)
    assert got[-1] == {1: "warning, held: ttc 5.0 s above 2.1 s"}
    lost = replace(threat(1, None), on_course=False, on_course_wide=False, miss_m=3.6)
    got = reasons(cfg, [(threat(1, 1.0),)] * 3 + [(lost,)] * 2)
    assert got[-1] == {1: "warning, held: path misses corridor by 3.6 m"}


def test_without_the_ego_motion_a_track_raises_at_most_a_caution(default_config: Config) -> None:
    """Vehicle CAN lost (``ego_known`` False): the threat comes from the image's growth and
    bearing alone; it may caution, never warn; its speed over ground (meaningless then) neither
    blocks it as "not moving" nor excuses a low probability; a warning issued before is held
    by the hold rules, not by hysteresis, and its reason says the ego motion is unknown."""
    from dataclasses import replace

    cfg = default_config.warning
    blind = replace(threat(1, 1.0), ego_known=False, moving=False)
    levels, events = run(cfg, [(blind,)] * 10)
    assert [e.level for e in events] == [1] and levels[-1] == 1
    assert reasons(cfg, [(blind,)] * 5)[-1] == {1: "caution, ego motion unknown"}
    weak = replace(blind, report=replace(blind.report, probability=0.4), speed_m_s=9.0)
    assert run(cfg, [(weak,)] * 10)[1] == []
    # a level 2 issued with the ego motion known is held for hold_s, then drops to a caution
    levels, events = run(cfg, [(threat(1, 1.0),)] * 4 + [(blind,)] * 40)
    assert [e.level for e in events] == [2, 1]
    assert events[1].t - events[0].t == pytest.approx(cfg.hold_s, abs=1.5 / FPS)


def test_a_track_whose_image_does_not_grow_as_its_path_implies_raises_no_level(
        default_config: Config) -> None:
    """A car 50 m ahead two lanes over drives along with the traffic: it keeps its bearing, its
    3-D state knows nothing yet of its speed along the line of sight and predicts it standing,
    closing at the ego speed (the path needs an expansion of 0.5/s); the scale cue measures its
    image not growing. No level, and the reason says so. The same track whose image grows,
    ``GROWTH_SIGMAS`` std above its measure, at least ``GROWTH_SHARE`` as fast as its path
    implies warns: a rigid body's growth and its 3-D state may differ by a fifth."""
    from dataclasses import replace

    cfg = default_config.warning
    still = replace(threat(1, 1.8), growth=(0.5, -0.08, 0.05))
    levels, events = run(cfg, [(still,)] * 10)
    assert events == [] and max(levels) == 0
    assert reasons(cfg, [(still,)] * 3)[-1][1] == "image grows at -0.08/s, its path needs 0.50/s"
    least = GROWTH_SHARE * 0.5
    for k, sd in ((0.5, 0.05), (0.4, 0.01), (least - (GROWTH_SIGMAS - 0.2) * 0.05, 0.05),
                  (0.9, 0.05)):
        grows = replace(threat(1, 1.8), growth=(0.5, k, sd))
        levels, events = run(cfg, [(grows,)] * 10)
        assert [e.level for e in events] == [2], k
    short = replace(threat(1, 1.8), growth=(0.5, least - (GROWTH_SIGMAS + 0.2) * 0.05, 0.05))
    levels, events = run(cfg, [(short,)] * 10)
    assert events == [], "growth GROWTH_SIGMAS std short of GROWTH_SHARE of the path's"


def assessed(cfg: Config, ahead_m: float, velocity: tuple[float, float], k: float,
             probability: float = 0.9, speed: float = 25.0, along_std: float = 8.0
             ) -> TrackThreat:
    """``assess`` on a track ``ahead_m`` in front of the camera in the middle of the lane, its
    3-D state moving at ``velocity`` over ground (known to 1 m/s across, ``along_std`` along),
    its image growing at ``k`` (1/s, std 0.05) by the scale cue, the car driving at ``speed``."""
    from appliance.decision.assess import assess
    from appliance.decision.cues import TrackCues
    from appliance.decision.cues.ground import GroundState
    from appliance.decision.cues.motion import MotionState
    from appliance.decision.cues.peaks import PeakState
    from appliance.decision.cues.scale import ScaleCueState
    from appliance.decision.frame import FrameContext
    from appliance.decision.ground_state import GroundTrack, camera_pose
    from appliance.decision.scale_ttc import ScaleState
    from appliance.decision.tracking import ImageTrack
    from appliance.messages import EgoMotion, SensorSample
    from appliance.pipeline import camera_from_config

    camera = camera_from_config(cfg)
    sensors = SensorSample(t=0.0, speed_m_s=speed, yaw_rate_rad_s=0.0)
    pose = camera_pose(cfg.mount, 0.0, sensors)
    zero = np.zeros(3)
    ego = EgoMotion(zero, np.array([0.0, 0.0, 1.0]), None, zero, np.array([0.0, 0.0, 1.0]), None,
                    100, True)
    f = FrameContext(t=0.0, dt=1 / FPS, pose=pose, sensors=sensors, ego=ego, odo=(0.0, 0.0, 0.0),
                     camera=camera, mount=cfg.mount, window_px=15, flow_std_px=0.3)
    ground = GroundTrack(x=np.array([cfg.mount.x_m + ahead_m, 0.0, *velocity]),
                         P=np.diag([4.0, 0.25, along_std ** 2, 1.0]), t_update=0.0, updates=8)
    scale = ScaleCueState(scale=ScaleState(k=k, var=0.05 ** 2, n=10), expansion=None,
                          trusted=True, ttc=None)
    cues = TrackCues(ground=ground, states={"ground": GroundState(ground=ground, fresh=True),
                                            "motion": MotionState(moved=True), "scale": scale,
                                            "peaks": PeakState(height_peak_m=1.5)})
    track = ImageTrack(uid=1, id=1, x=np.array([[320.0, 0.0, 0.0], [240.0, 0.0, 0.0]]),
                       P=np.tile(np.eye(3), (2, 1, 1)), size=(1.8 * camera.fx / ahead_m, 40.0),
                       age=20, misses=0, cluster=None, probability=probability)
    return assess(track, cues, f, cfg.warning)


@pytest.mark.parametrize("ahead_m, checked", [(55.0, True), (18.0, False)])
def test_the_growth_is_checked_where_the_ground_contact_is_too_far_to_measure_the_closing_speed(
        default_config: Config, ahead_m: float, checked: bool) -> None:
    """``assess`` on a track predicted standing ahead of a car at 25 m/s whose image the scale
    cue measures not growing. 55 m ahead one image row of its contact spans more than
    ``FAR_CONTACT_M_PER_PX`` of depth: the growth its path needs is reported and keeps it from a
    level. 18 m ahead the contact measures the closing speed itself: no growth is reported
    (there the scale cue of a walker's legs is the weaker of the two) and the path decides."""
    from appliance.decision.assess import FAR_CONTACT_M_PER_PX
    from appliance.decision.threat import contact_depth_per_px

    cfg = default_config
    th = assessed(cfg, ahead_m, (0.0, 0.0), -0.05)
    far = contact_depth_per_px(ahead_m, cfg.camera.fy, cfg.mount.z_m) >= FAR_CONTACT_M_PER_PX
    assert far == checked
    assert th.on_course and th.ttc is not None and th.ttc < cfg.warning.ttc_caution_s
    levels, events = run(cfg.warning, [(th,)] * 10)
    if checked:
        assert th.growth is not None
        implied, k, _ = th.growth
        assert implied == pytest.approx(25.0 / ahead_m, rel=0.05) and k == -0.05
        assert events == [] and max(levels) == 0
        assert str(indication(th, 3.0, cfg.warning)).startswith("image grows at -0.05/s")
    else:
        assert th.growth is None
        assert [e.level for e in events] == [2], indication(th, 3.0, cfg.warning)


@pytest.mark.parametrize("k, grows_standing", [(2.0, True), (0.5, False), (1.1, False)])
def test_a_fast_mover_whose_image_grows_as_the_road_there_needs_its_probability(
        default_config: Config, k: float, grows_standing: bool) -> None:
    """A patch of road 6.5 m ahead that the tracker drags along in front of a car at 14 m/s: its
    3-D state moves at 11 m/s, closing at 3 m/s (the path implies a growth of 0.46/s), but its
    image grows at 2.0/s, as anything standing there does (2.1/s): it is no fast mover, and its
    eq. 20 probability of 0.3 keeps it from a level. A lead car braking ahead, growing as its
    path implies (0.5/s), or nearer that than standing (1.1/s), is a fast mover and warns."""
    cfg = default_config
    th = assessed(cfg, 6.5, (11.0, 0.0), k, probability=0.3, speed=14.0, along_std=0.7)
    assert th.grows_standing == grows_standing
    assert th.speed_m_s is not None and th.speed_m_s >= FAST_MOVER_M_S
    assert th.on_course and th.ttc is not None and th.ttc < cfg.warning.ttc_warning_s
    levels, events = run(cfg.warning, [(th,)] * 10)
    if grows_standing:
        assert events == [] and indication(th, 3.0, cfg.warning) == "probability 0.30 below 0.50"
    else:
        assert [e.level for e in events] == [2]
