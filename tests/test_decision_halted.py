"""A lost mover seen standing where it stopped (decision/halted.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_decision_standing import CAM, DT, SPEED, frame

from appliance.config import Config
from appliance.decision.cues import TrackCues
from appliance.decision.cues.depth import DepthState
from appliance.decision.cues.peaks import PeakState
from appliance.decision.ground_state import GroundTrack, ground_in_camera
from appliance.decision.halted import (
    HaltProbe,
    halt_count,
    halt_probe,
    halted_threat,
    halted_threats,
)
from appliance.decision.lost_tracks import HALT_FRAMES, HALT_POINTS, LostTrack
from appliance.decision.tracking import ImageTrack
from appliance.decision.warnings import indication
from appliance.vision.probes import PointFlow

MOTION = (np.eye(3), np.array([0.0, 0.0, -SPEED * DT]))


def lost(cfg: Config, ahead_m: float, lateral_m: float = 0.0) -> LostTrack:
    """A pedestrian (0.5 m wide, 1.7 m tall) lost walking at 1.2 m/s ``ahead_m`` ahead of the
    camera, halted there."""
    x = cfg.mount.x_m + ahead_m
    track = ImageTrack(uid=1, id=7, x=np.array([[320.0, 0.0, 0.0], [240.0, 0.0, 0.0]]),
                       P=np.tile(np.eye(3), (2, 1, 1)), size=(0.5 * CAM.fx / ahead_m, 40.0),
                       age=20, misses=0, cluster=None, probability=0.8)
    ground = GroundTrack(x=np.array([x, lateral_m, -1.2, 0.0]), P=np.eye(4) * 0.25,
                         t_update=0.0, updates=10)
    cues = TrackCues(ground=ground,
                     states={"peaks": PeakState(probability=0.8, height_peak_m=1.7),
                             "depth": DepthState(depth=ahead_m, t=0.0)})
    return LostTrack(id=7, cues=cues, track=track, halted=np.array([x, lateral_m]))


def static_flow(p: HaltProbe, depth: float) -> PointFlow:
    """The flow (current minus ``frames_back`` frames ago) of static points now at camera depth
    ``depth`` (inf: at infinity), the camera driving straight along its axis."""
    x = CAM.undistort(p.points)
    g = (CAM.K @ p.t_m)[None, :2] - p.t_m[2] * x
    w = 0.0 if not np.isfinite(depth) else 1.0 / (depth - p.t_m[2])
    return PointFlow(g * w, np.ones(len(x), dtype=bool))


def probe(cfg: Config, ahead_m: float) -> HaltProbe:
    p = halt_probe(lost(cfg, ahead_m), frame(cfg), (MOTION,) * 6)
    assert p is not None
    return p


def test_the_probe_spans_the_baseline_and_starts_where_a_point_at_its_depth_was(
        default_config: Config) -> None:
    p = probe(default_config, 15.0)
    assert p.frames_back == round(0.15 / DT)
    assert p.t_m == pytest.approx([0.0, 0.0, -SPEED * DT * p.frames_back])
    # the probed box: from where the road seen is 1 / 0.55 times as far (0.585 m above the road
    # for the camera 1.3 m high) up to the mover's height (1.7 m)
    f = frame(default_config)
    foot = ground_in_camera(f.pose, lost(default_config, 15.0).halted)
    v_foot = float(CAM.project(foot[None])[0, 1])
    px = CAM.fy / float(foot[2])
    assert p.points[:, 1].max() == pytest.approx(v_foot - 0.45 * 1.3 * px, abs=0.5)
    assert p.points[:, 1].min() == pytest.approx(v_foot - 1.7 * px, abs=0.5)
    assert len(p.points) > 100
    then = p.points - static_flow(p, 15.0).flow
    assert p.guess == pytest.approx(then, abs=0.05)


def test_what_stands_where_it_stopped_fills_the_count_and_what_lies_beyond_does_not(
        default_config: Config) -> None:
    cfg = default_config
    p = probe(cfg, 15.0)
    n = len(p.points)
    # the object where it stopped (every point but those by the epipole, whose flow is too
    # short to tell a depth), or up to 25 % off the depth its track had
    full = halt_count(p, static_flow(p, 15.0), CAM)
    assert full >= 0.95 * n
    assert halt_count(p, static_flow(p, 18.75), CAM) == full
    assert halt_count(p, static_flow(p, 12.5), CAM) == full
    # the road seen above its feet is 1 / 0.55 times as far or more; the background at infinity
    assert halt_count(p, static_flow(p, 15.0 / 0.55), CAM) == 0
    assert halt_count(p, static_flow(p, np.inf), CAM) == 0
    # unmeasured points count for nothing
    unmeasured = replace(static_flow(p, 15.0), valid=np.zeros(n, dtype=bool))
    assert halt_count(p, unmeasured, CAM) == 0


def test_a_mover_seen_standing_where_it_stopped_warns_under_its_id(
        default_config: Config) -> None:
    cfg = default_config
    lt = lost(cfg, 12.0)
    f = frame(cfg)
    threats: list = []
    history = []
    for k in range(HALT_FRAMES):
        p = halt_probe(lt, f, (MOTION,) * 6)
        assert p is not None
        (lt,), threats = halted_threats((lt,), {("halt", 7, ""): p},
                                        {("halt", 7, ""): static_flow(p, 12.0)}, f, cfg.warning,
                                        cfg.obstacle.evidence_threshold)
        history.append(bool(threats))
    # seen standing once the median of the last HALT_FRAMES counts reaches the bar
    assert history == [False] * (HALT_FRAMES - 1) + [True]
    assert lt.stands() and lt.standing_seen == f.t
    # seen standing by its own test, it may still be assessed hidden (the occluder may be what
    # stands there): only an obstacle continuing it ends its coasting
    assert not lt.continued
    (th,) = threats
    assert th.report.id == 7 and th.standing and th.stopped and not th.suspected
    gap = 12.0 - (cfg.mount.vehicle_front_m - cfg.mount.x_m)
    assert th.ttc == pytest.approx(gap / SPEED, rel=0.05)
    assert indication(th, 2.0, cfg.warning) is None
    # the parallax cue's obstacle continuing it, or its coasted state while hidden, is its one
    # threat
    _, none = halted_threats((lt,), {}, {}, f, cfg.warning, cfg.obstacle.evidence_threshold, {7})
    assert none == []
    # what lies beyond leaves the count short: it walked on
    gone = replace(lt, halt=(0.0,) * HALT_FRAMES, standing_seen=None)
    p = halt_probe(gone, f, (MOTION,) * 6)
    assert p is not None
    (gone,), threats = halted_threats((gone,), {("halt", 7, ""): p},
                                      {("halt", 7, ""): static_flow(p, 20.4)}, f, cfg.warning,
                                      cfg.obstacle.evidence_threshold)
    assert threats == [] and not gone.stands()


def test_it_stands_only_on_a_median_of_measured_counts() -> None:
    lt = LostTrack(id=1, cues=TrackCues())
    assert not lt.stands()
    bar = HALT_POINTS
    assert replace(lt, halt=(bar, bar, bar)).stands()
    assert replace(lt, halt=(0.0, bar, bar)).stands()
    assert not replace(lt, halt=(0.0, 0.0, bar)).stands()
    assert not replace(lt, halt=(bar, bar, float("nan"))).stands()


def test_a_mover_stopped_beside_the_path_is_no_threat_in_it(default_config: Config) -> None:
    cfg = default_config
    f = frame(cfg)
    beside = halted_threat(lost(cfg, 12.0, lateral_m=3.0), f, cfg.warning,
                           cfg.obstacle.evidence_threshold)
    assert beside is not None and not beside.on_course
    assert indication(beside, 2.0, cfg.warning).startswith("path misses corridor")


def test_static_scenery_the_tracker_followed_for_a_while_is_no_mover_that_stopped(
        default_config: Config) -> None:
    """A track that never showed the probability a level needs (a ghost on the outside of a
    bend, dropped where the roadside stands in the path) raises no threat standing there."""
    cfg = default_config
    ghost = lost(cfg, 12.0)
    ghost = replace(ghost, cues=ghost.cues.replaced(peaks=PeakState(probability=0.35,
                                                                    height_peak_m=1.7)))
    assert halted_threat(ghost, frame(cfg), cfg.warning, cfg.obstacle.evidence_threshold) is None
    assert halted_threat(lost(cfg, 12.0), frame(cfg), cfg.warning,
                         cfg.obstacle.evidence_threshold) is not None


def test_a_mover_lost_at_speed_is_not_looked_for_where_it_was_lost(
        default_config: Config) -> None:
    """A car crossing far ahead, lost at 7 m/s, runs on for metres: what stands where it was
    lost (a parked car) is something else."""
    cfg = default_config
    walker = lost(cfg, 30.0, lateral_m=-2.5)
    g = walker.cues.ground
    car = replace(walker, cues=TrackCues(ground=replace(g, x=np.array([*g.x[:2], -7.0, 0.0])),
                                         states=walker.cues.states))
    assert halt_probe(walker, frame(cfg), (MOTION,) * 6) is not None
    assert halt_probe(car, frame(cfg), (MOTION,) * 6) is None
