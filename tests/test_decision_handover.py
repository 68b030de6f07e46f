"""A mover that stops in the path stays one track (decision/handover.py, lost_tracks.halted)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_decision_standing import STATIC, frame

from appliance.config import Config, HiddenConfig
from appliance.decision.assess import TrackThreat
from appliance.decision.cues import TrackCues
from appliance.decision.ground_state import GroundModel, GroundTrack
from appliance.decision.handover import continued, obstacle_position, one_threat
from appliance.decision.lost_tracks import LostTrack, coast_lost, coasted_track, halted_step
from appliance.decision.standing import Obstacle, obstacle_threat
from appliance.decision.tracking import TrackerState
from appliance.decision.warnings import WarningState, indication, warning_step
from appliance.messages import SensorSample, TrackReport


def obstacle(depth: float, lateral: tuple[float, float] = (-0.4, 0.0)) -> Obstacle:
    return Obstacle(id=20, depth_m=depth, lateral_m=lateral, evidence=30.0, since=0.0, seen=0.0)


def test_an_obstacle_continues_the_mover_that_stopped_where_it_stands(
        default_config: Config) -> None:
    m = default_config.mount
    ob = obstacle(14.0)
    x = m.x_m + 14.0
    # the first depth of an obstacle is biased far: a quarter of the distance is in the gate
    assert continued(ob, m, 0.0, [(7, np.array([x - 3.0, 0.1]))]) == 7
    # the nearer of two in the gate
    assert continued(ob, m, 0.0, [(7, np.array([x - 3.0, 0.1])),
                                  (9, np.array([x + 0.5, -0.3]))]) == 9
    # too far along the path, or beside it (a pedestrian stopped at the kerb)
    assert continued(ob, m, 0.0, [(7, np.array([x + 6.0, -0.2]))]) is None
    assert continued(ob, m, 0.0, [(7, np.array([x, 2.5]))]) is None
    assert continued(ob, m, 0.0, [(7, np.array([np.nan, 0.0]))]) is None
    assert continued(ob, m, 0.0, []) is None


def test_the_obstacle_lies_on_the_predicted_path(default_config: Config) -> None:
    m = default_config.mount
    straight = obstacle_position(obstacle(20.0, (-0.4, 0.4)), m, 0.0)
    assert straight == pytest.approx([m.x_m + 20.0, 0.0])
    bend = obstacle_position(obstacle(20.0, (-0.4, 0.4)), m, 1.0 / 75.0)
    # a left bend (positive curvature): the path, and the obstacle on it, lie to the left
    assert bend[1] == pytest.approx((m.x_m + 20.0) ** 2 / (2 * 75.0), rel=0.05)


def test_a_lost_track_halted_stands_still_as_the_car_drives_on() -> None:
    s = SensorSample(t=0.0, speed_m_s=10.0, yaw_rate_rad_s=0.0)
    p = halted_step(np.array([20.0, 1.0]), 0.1, s)
    assert p == pytest.approx([19.0, 1.0])
    turning = SensorSample(t=0.0, speed_m_s=10.0, yaw_rate_rad_s=0.2)
    q = halted_step(np.array([20.0, 0.0]), 0.5, turning)
    # the car turned left by 0.1 rad: a point straight ahead is now to its right
    assert q[1] < -1.0 and q[0] == pytest.approx(15.0, abs=0.3)
    assert halted_step(None, 0.1, s) is None


def threat(ident: int, standing: bool, moving: bool) -> TrackThreat:
    report = TrackReport(id=ident, bbox=(0.0, 0.0, 1.0, 1.0), probability=0.9, flow=(0.0, 0.0),
                         ttc_s=1.0, distance_m=10.0, bearing_rad=0.0)
    return TrackThreat(report=report, on_course=True, on_course_wide=True, moving=moving,
                       standing=standing)


def test_a_live_track_and_its_obstacle_are_one_threat() -> None:
    other = threat(3, False, True)
    moving, still, ob = threat(7, False, True), threat(7, False, False), threat(7, True, False)
    assert one_threat([other, moving, ob], 7) == [other, moving]
    assert one_threat([other, still, ob], 7) == [other, ob]
    assert one_threat([other, ob], 7) == [other, ob]


def test_a_stopped_mover_does_not_wait_to_be_seen_coming_nearer(default_config: Config) -> None:
    cfg = default_config
    brief = Obstacle(id=7, depth_m=15.0, lateral_m=(-0.4, 0.4), evidence=40.0, since=0.0,
                     seen=0.0, history=STATIC[-2:])
    th = obstacle_threat(brief, frame(cfg), cfg.warning, cfg.obstacle.evidence_threshold)
    assert indication(th, 2.0, cfg.warning) == "standing: not yet seen coming nearer"
    stopped = obstacle_threat(dataclasses.replace(brief, stopped=True), frame(cfg), cfg.warning,
                              cfg.obstacle.evidence_threshold)
    assert stopped.stopped and indication(stopped, 2.0, cfg.warning) is None
    # the roadside still holds it back
    side = obstacle_threat(dataclasses.replace(brief, stopped=True, roadside=True), frame(cfg),
                           cfg.warning, cfg.obstacle.evidence_threshold)
    assert "roadside" in indication(side, 2.0, cfg.warning)


def test_the_obstacle_box_reaches_the_stopped_movers_height(default_config: Config) -> None:
    cfg = default_config
    ob = obstacle(15.0, (-0.4, 0.4))
    low = obstacle_threat(ob, frame(cfg), cfg.warning, 16.0).report.bbox
    tall = obstacle_threat(dataclasses.replace(ob, top_m=1.8), frame(cfg), cfg.warning,
                           16.0).report.bbox
    assert tall[3] == pytest.approx(low[3]) and tall[1] < low[1] - 20.0


def test_a_stopped_mover_warns_from_what_only_may_stand_there(default_config: Config) -> None:
    """Short of the evidence threshold something only may stand in the path: a caution at
    most. A mover seen to stop there is known to be an object: its obstacle warns."""
    cfg = default_config
    weak = Obstacle(id=7, depth_m=12.0, lateral_m=(-0.4, 0.4), evidence=9.0, since=0.0,
                    seen=0.0, history=STATIC, confirmed=False, confirmed_at=None)
    levels = {}
    for stopped in (False, True):
        th = obstacle_threat(dataclasses.replace(weak, stopped=stopped), frame(cfg),
                             cfg.warning, cfg.obstacle.evidence_threshold)
        assert th.ttc is not None and th.ttc < cfg.warning.ttc_warning_s
        state = WarningState()
        for k in range(6):
            state, _, _, _ = warning_step(state, (th,), k * 0.1, k, cfg.warning, frame_dt=0.1)
        levels[stopped] = state.level
    assert levels == {False: 1, True: 2}


def lost(standing_seen: float | None, continued: bool = True) -> LostTrack:
    ground = GroundTrack(x=np.array([20.0, 0.0, -1.4, 0.0]), P=np.eye(4) * 0.25, t_update=0.0,
                         updates=10)
    return LostTrack(id=7, cues=TrackCues(ground=ground), halted=np.array([20.0, 0.0]),
                     standing_seen=standing_seen, continued=continued)


def test_a_stopped_mover_continued_by_its_obstacle_is_kept_where_it_stands() -> None:
    """A lost track continued by an obstacle is no longer coasted: it is kept, standing where
    the obstacle stood, for ``keep_s`` after the obstacle was last seen, so that an obstacle
    found there again after a gap continues it under its id."""
    cfg = HiddenConfig(keep_s=2.0, warn_s=1.5, max_level=2)
    sensors = SensorSample(t=0.0, speed_m_s=10.0, yaw_rate_rad_s=0.0)
    none = TrackerState()

    def coast(lt: LostTrack, t: float) -> tuple[LostTrack, ...]:
        return coast_lost(none, {}, (lt,), none, t, 0.1, sensors, GroundModel(), cfg)

    # 2.5 s after its last ground contact: a coasting track is forgotten ...
    assert coast(lost(None, False), 2.5) == ()
    # ... one whose obstacle was seen 1 s before is kept, the car 1 m nearer to where it stands
    kept = coast(lost(1.5), 2.5)
    assert len(kept) == 1 and kept[0].halted == pytest.approx([19.0, 0.0])
    assert coast(lost(0.4), 2.5) == ()
    # and it is not assessed from its coasted state
    assert coasted_track(kept[0], 2.5, None, 1.9, None, 10.0) is None  # type: ignore[arg-type]
