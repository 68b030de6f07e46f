"""The decision stage (section 4 + the 3-D state): particles in, tracks and warnings out.

Two pure calls per frame, with vision's measurement of the pixels decision asks about in
between (decision never sees an image):

1. :func:`observe`: the particle weights filtered into p(x) (probability_map.py), clustered
   (clustering.py, eqs. 19-20) and tracked by the paper's five Kalman rules (tracking.py);
   the hidden tracks coasted (lost_tracks.py); and the probes: the pixels whose flow the cues
   (``cues/``) and the hidden-track tests (occlusion.py) need this frame.
2. :func:`decide`, with the flow vision measured there: per track, every cue of ``CUES`` in
   order (3-D state, scale change, ...); per confirmed track its threat (assess.py); the
   hidden tracks still covered, from their coasted states; then the warning levels, and each
   track's reason (warnings.py).

Time is an argument, nothing is read from a clock and there is no randomness: a replay is
deterministic.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from appliance.config import Config
from appliance.decision.assess import TrackThreat, assess
from appliance.decision.clustering import find_clusters
from appliance.decision.crossing_velocity import odometry_step
from appliance.decision.cues import CueInput, Probe, TrackCues, probes, update_cues
from appliance.decision.cues.ground import ground_model
from appliance.decision.cues.peaks import shown
from appliance.decision.frame import (
    FrameContext,
    can_speed,
    finite,
    frame_motion,
    measure_track,
    speed_slope,
)
from appliance.decision.ground_state import camera_pose, update_body_pitch
from appliance.decision.handover import (
    STOPPING_M_S,
    continued,
    mover_height,
    obstacle_position,
    one_threat,
)
from appliance.decision.halted import halted_probes, halted_threats
from appliance.decision.hidden import hidden_probes, hidden_threats
from appliance.decision.lost_tracks import coast_lost, moved_within, reacquire
from appliance.decision.occlusion import CoastProbe
from appliance.decision.probability_map import empty_map, spatio_temporal_filter
from appliance.decision.standing import (
    CorridorProbe,
    corridor_probe,
    init_standing,
    inside,
    obstacle_threat,
    standing_step,
)
from appliance.decision.state import DecisionOutput, DecisionState, Observation, ProbeKey
from appliance.decision.tracking import ImageModel, TrackerState, track_step
from appliance.decision.warnings import WarningState, pool_covered, warning_step
from appliance.messages import EgoMotion, ParticleSet, ProbabilityMap, SensorSample
from appliance.vision.geometry import PinholeCamera
from appliance.vision.probes import PointFlow

__all__ = ["DecisionOutput", "DecisionState", "Observation", "decide", "init_decision_state",
           "observe"]


OBSTACLE_PROBE = ("obstacle", 0, "")


def moved(cues: TrackCues | None) -> bool:
    """Whether a track has shown independent motion over ground (the motion cue)."""
    m = cues.get("motion") if cues is not None else None
    return bool(m is not None and m.moved)


def init_decision_state(cfg: Config, camera: PinholeCamera) -> DecisionState:
    return DecisionState(
        prob=empty_map(camera, cfg.probability_map.scale),
        tracker=TrackerState(),
        cues={},
        warning=WarningState(),
        body_pitch=0.0,
        pose=None,
        t=None,
        model=ImageModel.from_config(cfg.tracking),
        standing=init_standing(cfg.obstacle),
    )


def observe(state: DecisionState, frame_index: int, t: float, particles: ParticleSet,
            ego: EgoMotion, sensors: SensorSample, cfg: Config, camera: PinholeCamera
            ) -> Observation:
    """Step 1 of a frame (module docstring): p(x), clusters, tracks, hidden tracks, probes."""
    dt = (t - state.t) if state.t is not None and t > state.t else 1.0 / cfg.camera.fps
    body_pitch = state.body_pitch
    if state.pose is not None:
        body_pitch = update_body_pitch(body_pitch, ego, state.pose, dt)
    pose = camera_pose(cfg.mount, body_pitch, sensors)
    odo = odometry_step(state.odo, finite(sensors.speed_m_s), finite(sensors.yaw_rate_rad_s), dt) \
        if state.t is not None else state.odo
    accel = speed_slope(state.accel, state.speed, can_speed(sensors), dt)
    frame = FrameContext(t=t, dt=dt, pose=pose, sensors=sensors, ego=ego, odo=odo, camera=camera,
                         mount=cfg.mount, window_px=particles.window_px,
                         flow_std_px=particles.flow_std_px, accel=accel)
    prob = spatio_temporal_filter(state.prob, particles, ego.rotation, camera, cfg.probability_map)
    clusters = find_clusters(prob, cfg.probability_map.scale, particles, cfg.clustering,
                             (camera.width, camera.height), halo_px=frame.halo_px)
    tracker = track_step(state.tracker, clusters, cfg.tracking, state.model)
    lost = coast_lost(state.tracker, state.cues, state.lost, tracker, t, dt, sensors,
                      ground_model(cfg.cue.ground), cfg.hidden)
    asked: dict[ProbeKey, Probe | CoastProbe | CorridorProbe] = {}
    for tr in tracker.tracks:
        for name, p in probes(state.cues.get(tr.uid), tr, frame, cfg.cue):
            asked[("cue", tr.uid, name)] = p
    asked.update(hidden_probes(lost, frame, cfg.hidden))
    before = state.standing if state.standing is not None else init_standing(cfg.obstacle)
    asked.update(halted_probes(lost, frame, before.motions))
    corridor = corridor_probe(pose, camera, ego, sensors, dt, cfg.mount,
                              cfg.warning.corridor_margin_m, particles.window_px,
                              before.motions, cfg.obstacle)
    if corridor is not None:
        asked[OBSTACLE_PROBE] = corridor
    return Observation(frame_index=frame_index, frame=frame, body_pitch=body_pitch, prob=prob,
                       clusters=clusters, tracker=tracker, lost=lost, probes=asked)


def decide(state: DecisionState, obs: Observation, flows: Mapping[ProbeKey, PointFlow] | None,
           cfg: Config) -> tuple[DecisionState, DecisionOutput]:
    """Step 2 of a frame (module docstring). ``flows``: what vision measured at
    ``obs.requests()``; None without the previous frame (nothing measured)."""
    f = obs.frame
    measured = flows if flows is not None else {}
    model = ground_model(cfg.cue.ground)
    lost = obs.lost
    cues: dict[int, TrackCues] = {}
    threats: list[TrackThreat] = []
    tracks = list(obs.tracker.tracks)
    for i, tr in enumerate(tracks):
        before = state.cues.get(tr.uid)
        meas = measure_track(tr, f, model)
        found = None
        if meas.contact is not None and (before is None or before.ground is None) and lost:
            found = reacquire(lost, meas.contact)
        probed = {name: (p, measured[(kind, uid, name)])
                  for (kind, uid, name), p in obs.probes.items()
                  if (kind, uid) == ("cue", tr.uid) and (kind, uid, name) in measured
                  and isinstance(p, Probe)}
        x = CueInput(track=tr, meas=meas, frame=f, found=found.cues if found else None)
        cues[tr.uid] = update_cues(before, x, cfg.cue, probed)
        if found is not None:
            # the reacquired track continues the lost one under its id
            lost = tuple(lt for lt in lost if lt is not found)
            tracks[i] = tr = replace(tr, id=found.id)
        if tr.confirmed:
            threats.append(assess(shown(tr, cues[tr.uid].states), cues[tr.uid], f, cfg.warning))
    threats = pool_covered(threats)
    corridor = obs.probes.get(OBSTACLE_PROBE)
    cp = corridor if isinstance(corridor, CorridorProbe) else None
    mover_p = np.zeros(0)
    if cp is not None:
        moving = [tr.bbox for tr in tracks if tr.confirmed and moved(cues.get(tr.uid))]
        mover_p = np.maximum(
            ProbabilityMap(p=obs.prob, scale=cfg.probability_map.scale).at(cp.points),
            inside(cp.points, moving))
    before_standing = state.standing if state.standing is not None else init_standing(cfg.obstacle)
    standing, next_id = standing_step(
        before_standing, cp, measured.get(OBSTACLE_PROBE), mover_p, f.t, f.dt, f.speed,
        frame_motion(f.ego, f.sensors, f.dt), f.camera, f.mount, cfg.warning.corridor_margin_m,
        obs.tracker.next_id, cfg.obstacle)
    ob = standing.obstacle
    curvature = f.yaw_rate / f.speed if f.speed > 0.1 else 0.0
    if ob is not None and ob.since == f.t:
        # new: it continues the mover that came to a stop where it stands (handover.py)
        movers = [(lt.id, lt.halted) for lt in lost if lt.halted is not None]
        heights = {lt.id: mover_height(lt.cues) for lt in lost}
        for tr in tracks:
            g = cues[tr.uid].ground
            if tr.confirmed and tr.id is not None and g is not None and g.speed < STOPPING_M_S \
                    and moved_within(cues[tr.uid], f.t, cfg.hidden.keep_s):
                movers.append((int(tr.id), g.position))
                heights[int(tr.id)] = mover_height(cues[tr.uid])
        ident = continued(ob, f.mount, curvature, movers)
        if ident is not None:
            top = heights.get(ident)
            ob = replace(ob, id=ident, stopped=True, top_m=top if top is not None else ob.top_m)
            standing = replace(standing, obstacle=ob)
            next_id = obs.tracker.next_id
    if ob is not None:
        # its track, if it was lost, is continued by the obstacle: no longer coasted, it stands
        # where the obstacle does, for an obstacle found there again to continue it
        lost = tuple(replace(lt, standing_seen=f.t, continued=True,
                             halted=obstacle_position(ob, f.mount, curvature))
                     if lt.id == ob.id else lt for lt in lost)
    lost, hidden = hidden_threats(lost, obs.probes, measured, f, cfg.hidden, cfg.warning)
    # seen standing where it stopped, unless assessed otherwise: hidden (what stands there may
    # be the occluder), or where the parallax cue's obstacle stands (it continues the mover, or
    # describes what stands there: the roadside, at the outside of a bend)
    assessed = {th.report.id for th in hidden}
    if ob is not None:
        assessed |= {lt.id for lt in lost if lt.id == ob.id or lt.halted is not None
                     and continued(ob, f.mount, curvature, [(lt.id, lt.halted)]) == lt.id}
    lost, halted = halted_threats(lost, obs.probes, measured, f, cfg.warning,
                                  cfg.obstacle.evidence_threshold, assessed)
    threats.extend(hidden + halted)
    if ob is not None and ob.seen == f.t:
        threats.append(obstacle_threat(ob, f, cfg.warning, cfg.obstacle.evidence_threshold))
        threats = one_threat(threats, ob.id)
    threats.sort(key=lambda th: th.report.id)
    warning, events, warned, reasons = warning_step(
        state.warning, tuple(threats), f.t, obs.frame_index, cfg.warning, frame_dt=f.dt,
        released=frozenset(lt.id for lt in lost if lt.off_course),
        hidden_max_level=cfg.hidden.max_level)
    tracker = replace(obs.tracker, tracks=tuple(tracks), next_id=next_id)
    new_state = DecisionState(prob=obs.prob, tracker=tracker, cues=cues, warning=warning,
                              body_pitch=obs.body_pitch, pose=f.pose, t=f.t, model=state.model,
                              lost=lost, odo=f.odo, speed=can_speed(f.sensors), accel=f.accel,
                              standing=standing)
    out = DecisionOutput(
        prob_map=ProbabilityMap(p=obs.prob, scale=cfg.probability_map.scale),
        clusters=obs.clusters,
        tracks=tuple(replace(th.report, reason=reasons[th.report.id]) for th in threats),
        warnings=events,
        warning_level=warning.level,
        warning_track=warned,
    )
    return new_state, out
