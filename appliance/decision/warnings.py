"""Warning levels a driver can trust: thresholds, persistence, hysteresis, hold.

Per confirmed track and frame the threat assessment (threat.py) says whether its
predicted path meets the ego corridor and with what TTC. From that:

* **Indication** (:func:`indication`, the one place that decides whether a track may
  raise a level, and says why not). Level 2 is indicated while the path meets the corridor
  (``corridor_margin_m``) and TTC <= ``ttc_warning_s``; level 1 with
  ``ttc_caution_s``; only for tracks that have shown independent motion over
  ground (the motion cue): the appliance warns of moving
  objects, and a false detection on the static scene converges to standing still;
  and only while the track's regions carry a mean probability of independent
  motion (eq. 20, smoothed) of at least ``min_probability``: false detections on
  road texture are weak and patchy, real movers are not; and, with a ground contact,
  only for a box at least ``min_height_m`` tall at that depth (a road user, not a strip
  of road); and, where its ground contact is too far to measure its speed along the line of sight
  (``assess.FAR_CONTACT_M_PER_PX``), only while its image grows as its predicted path implies (the
  scale cue's expansion rate, once trusted, ``GROWTH_SIGMAS`` std above it, at least
  ``GROWTH_SHARE`` of the closing speed over depth): a car 50 m ahead that keeps its bearing as it
  drives along with the traffic is predicted standing, closing at the ego speed, and its image does
  not grow. A track moving over ground at ``FAST_MOVER_M_S`` or more (a car, a cyclist; the speed it
  moves at least, 2 std below its estimate) needs no ``min_probability``: a lead car at the epipole
  shows little independent flow; unless its image grows nearer as something standing there would
  than as its path implies (``TrackThreat.grows_standing``).
  A hidden track, assessed from its coasted 3-D state, needs ``HIDDEN_MIN_PROBABILITY``
  (its highest while seen) and raises at most ``hidden.max_level``. An obstacle that only
  may stand in the path (its evidence short of ``obstacle.evidence_threshold``, standing.py)
  raises at most a caution.
* **Without the ego motion** (vehicle CAN stale or absent, PTU lost) the 3-D states' velocities
  over ground mean nothing: a track is judged from its image's growth and its bearing alone
  (``assess``), needs its probability whatever its speed, and raises at most a caution; a
  warning already issued is held by the hold rules below, not by hysteresis.
* **Minimum persistence.** A track raises a level only after indicating it in
  ``min_persistence_frames`` consecutive frames: no single-frame warnings. The
  indication looks ahead by the window's length (threshold + (frames - 1) * frame
  interval), so a steadily falling TTC is issued when it reaches the threshold.
* **Hysteresis.** Once a track holds a level it keeps it while TTC <= threshold +
  ``hysteresis_s`` and the path meets the corridor widened by
  ``assess.CORRIDOR_HYSTERESIS_M``: a TTC oscillating around a threshold does not flicker.
* **Hold.** An issued level is not lowered within ``hold_s`` of being issued. If
  the warned track is lost, or its TTC becomes unknown (it left the image, went
  under the bonnet, lost its ground contact just before contact), the level is
  held until its last predicted contact time has passed (at least ``hold_s``):
  a warning is never cleared because the object came too close to see. A hidden track
  known to be off its course (its head seen to stop, ``released``) is held for ``hold_s``
  only.

The issued level is the highest over all tracks (ties: the track already
warned about, then the smallest TTC). A state change -- level or warned track --
produces one :class:`WarningEvent`. Every track's reason (``tracks.jsonl``) says where it
stands: "warning" / "caution" for the warned track (a caution on something that only may
stand, within the warning's TTC, says so), else what keeps it from a level.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from appliance.config import WarningConfig
from appliance.decision.assess import TrackThreat
from appliance.messages import TrackReport, WarningEvent

MIN_CLOSING = 0.5             # a standing obstacle comes nearer by at least this per metre driven
FAST_MOVER_M_S = 5.0          # m/s over ground: a car or cyclist needs no min_probability
HIDDEN_MIN_PROBABILITY = 0.55  # min_probability of a hidden track (its highest while seen)
GROWTH_SIGMAS = 3.0           # far away, an image growing at most GROWTH_SHARE as fast as its
GROWTH_SHARE = 0.5            #   path implies (this many std) keeps a track from a level
LEVEL_NAMES = {1: "caution", 2: "warning"}
ONLY_MAY_STAND = "only may stand, its evidence short of the threshold"   # why a caution
#                  within the warning's TTC is no warning (standing.SUSPECT_SHARE)


@dataclass(frozen=True)
class WarningState:
    """level: issued level 0/1/2; track: id behind it; since: time it was issued (s);
    streaks: per track id, consecutive frames indicating (level 1, level 2);
    last: the last report of the warned track and the time it was seen."""

    level: int = 0
    track: int | None = None
    since: float = float("-inf")
    streaks: dict[int, tuple[int, int]] = field(default_factory=dict)
    last: TrackReport | None = None
    last_seen: float = float("-inf")


def pool_covered(threats: list[TrackThreat]) -> list[TrackThreat]:
    """Each seen track's ``evidence``: the highest eq. 20 probability among itself and the tracks
    whose box centre its box covers. A near pedestrian's particles gather in separate regions,
    its feet (the ground contact, the TTC) and its head and shoulders; the feet track's outline
    reaches up over the others: one object."""
    out = []
    for th in threats:
        u0, v0, u1, v1 = th.report.bbox
        p = th.report.probability
        for other in threats:
            a0, b0, a1, b1 = other.report.bbox
            if other is not th and u0 <= 0.5 * (a0 + a1) <= u1 and v0 <= 0.5 * (b0 + b1) <= v1:
                p = max(p, other.report.probability)
        out.append(replace(th, evidence=p) if p > th.report.probability else th)
    return out


def indication(th: TrackThreat, threshold: float, cfg: WarningConfig) -> str | None:
    """Why ``th`` does not indicate a level whose TTC threshold is ``threshold`` (s); None when
    it does. The one place that decides whether a track may warn: it moves over ground, it
    stands up from the road, its evidence of independent motion is strong enough (or it is a
    fast mover), its path meets the corridor, its time to collision is within the threshold,
    and, far away, its image grows as its path implies."""
    if th.ego_known and not th.moving and not th.standing:
        return "not moving over ground"
    if th.standing and th.roadside:
        return "stands at the roadside, which comes nearer beside it (a bend)"
    if th.standing and th.closing is None and not th.stopped:
        return "standing: not yet seen coming nearer"
    if th.standing and th.closing is not None and th.closing < MIN_CLOSING:
        return f"standing: comes {th.closing:.2f} m nearer per metre driven"
    if th.height_m is not None and th.height_m < cfg.min_height_m:
        return f"box {th.height_m:.2f} m tall, below {cfg.min_height_m:.2f} m"
    p = th.report.probability if th.evidence is None else th.evidence
    p_min = HIDDEN_MIN_PROBABILITY if th.coasted else cfg.min_probability
    fast = th.ego_known and th.speed_m_s is not None and th.speed_m_s >= FAST_MOVER_M_S \
        and not th.grows_standing
    if p < p_min and not fast and not th.standing:
        return f"probability {p:.2f} below {p_min:.2f}"
    if not th.on_course:
        if th.miss_m is None:
            return "path misses corridor"
        if th.miss_ahead:
            return f"path stays {th.miss_m:.1f} m ahead in the corridor"
        return f"path misses corridor by {th.miss_m:.1f} m"
    if th.ttc is None:
        return "no time to collision"
    if th.ttc > threshold:
        return f"ttc {th.ttc:.1f} s above {threshold:.1f} s"
    if th.growth is not None:
        implied, k, sd = th.growth
        if k + GROWTH_SIGMAS * sd < GROWTH_SHARE * implied:
            return f"image grows at {k:.2f}/s, its path needs {implied:.2f}/s"
    return None


def holds(th: TrackThreat, threshold: float, hysteresis: float) -> bool:
    """Whether the track already holding a level keeps it: TTC within the threshold plus the
    hysteresis and the path meeting the widened corridor."""
    return th.ttc is not None and th.on_course_wide and th.ttc <= threshold + hysteresis


def warning_step(state: WarningState, threats: tuple[TrackThreat, ...], t: float, frame: int,
                 cfg: WarningConfig, frame_dt: float = 0.0,
                 released: frozenset[int] = frozenset(), hidden_max_level: int = 2
                 ) -> tuple[WarningState, tuple[WarningEvent, ...], TrackReport | None,
                            dict[int, str]]:
    """One frame: (new state, events of this frame, the report behind the issued level, each
    track's reason: "warning" / "caution" for the warned track, else what keeps it from one).

    frame_dt: the frame interval (s); the persistence window looks ahead by its own
    length, ``(min_persistence_frames - 1) * frame_dt``, so a steadily falling TTC is
    issued when it reaches the threshold rather than one window later.
    released: ids of tracks known to be off their course (a hidden pedestrian whose head was
    seen to stop, occlusion.py): a level they raised is not held until their contact is due,
    only for ``hold_s``. hidden_max_level: the highest level a hidden (coasted) track raises
    (an issued level is held as any other).
    """
    lookahead = max(cfg.min_persistence_frames - 1, 0) * max(frame_dt, 0.0)
    thresholds = {1: cfg.ttc_caution_s, 2: cfg.ttc_warning_s}
    streaks: dict[int, tuple[int, int]] = {}
    candidates: list[tuple[int, float, int, TrackThreat]] = []
    levels: dict[int, int] = {}
    blocked: dict[int, str] = {}
    for th in threats:
        tid = th.report.id
        old = state.streaks.get(tid, (0, 0))
        why1 = indication(th, thresholds[1] + lookahead, cfg)
        s1 = old[0] + 1 if why1 is None else 0
        s2 = old[1] + 1 if indication(th, thresholds[2] + lookahead, cfg) is None else 0
        if not th.ego_known or th.suspected:   # no level 2 from an ego motion it does not
            s2 = 0                              # know, nor from what only may stand
        if th.coasted and hidden_max_level < 2:   # an issued level is held
            s2 = 0
            if hidden_max_level < 1:
                s1 = 0
                why1 = why1 or "hidden: raises no level"
        streaks[tid] = (s1, s2)
        level = 0
        for k, streak in ((2, s2), (1, s1)):
            holding = (state.track == tid and state.level >= k and (k < 2 or th.ego_known)
                       and holds(th, thresholds[k], cfg.hysteresis_s))
            if streak >= cfg.min_persistence_frames or holding:
                level = k
                break
        levels[tid] = level
        if level > 0:
            ttc = th.ttc if th.ttc is not None else float("inf")
            candidates.append((level, ttc, tid, th))
        else:
            blocked[tid] = why1 or f"caution indicated {s1} of {cfg.min_persistence_frames} frames"
    # highest level; then the track already warned about; then the smallest TTC
    candidates.sort(key=lambda c: (-c[0], c[2] != state.track, c[1], c[2]))
    present = {th.report.id: th for th in threats}
    if candidates:
        level, _, tid, best = candidates[0]
        new_track: int | None = tid
        report: TrackReport | None = best.report
    else:
        level, new_track, report = 0, None, None

    # hold: never lower an issued level within hold_s, nor while a lost track's contact is due
    if level < state.level:
        held = t < state.since + cfg.hold_s
        warned = present.get(state.track) if state.track is not None else None
        unknown = warned is None or warned.ttc is None
        if state.track is not None and unknown and state.last is not None \
                and state.track not in released:
            due = state.last_seen + max(cfg.hold_s, state.last.ttc_s or 0.0)
            held = held or t < due
        if held:
            level, new_track = state.level, state.track
            if warned is not None and not unknown:
                report = warned.report
            else:
                report = _extrapolated(state.last, t - state.last_seen)
                if report is not None and warned is not None:
                    report = replace(report, bbox=warned.report.bbox,
                                     bearing_rad=warned.report.bearing_rad)
    seen = (new_track is not None and new_track in present
            and present[new_track].ttc is not None)
    events: tuple[WarningEvent, ...] = ()
    if level != state.level or (level > 0 and new_track != state.track):
        since = t
        if level == 0:
            cleared = state.track
            rep = present[cleared].report if cleared is not None and cleared in present else None
            events = (WarningEvent(t=t, frame=frame, level=0, track=cleared,
                                   bbox=rep.bbox if rep else None, ttc_s=rep.ttc_s if rep else None,
                                   distance_m=rep.distance_m if rep else None,
                                   bearing_rad=rep.bearing_rad if rep else None),)
        else:
            assert report is not None
            events = (WarningEvent(t=t, frame=frame, level=level, track=new_track, bbox=report.bbox,
                                   ttc_s=report.ttc_s, distance_m=report.distance_m,
                                   bearing_rad=report.bearing_rad),)
    else:
        since = state.since
    new_state = WarningState(
        level=level,
        track=new_track if level > 0 else None,
        since=since,
        streaks=streaks,
        last=(present[new_track].report if seen and new_track is not None else state.last)
        if level > 0 else None,
        last_seen=t if seen else state.last_seen,
    )
    reasons: dict[int, str] = {}
    for th in threats:
        tid = th.report.id
        if level > 0 and tid == new_track:
            why = LEVEL_NAMES[level]
            if levels[tid] < level:   # held: and what it no longer meets
                lapsed = indication(th, thresholds[level] + lookahead, cfg)
                why += ", held" + (f": {lapsed}" if lapsed else "")
            elif level == 1 and th.suspected and th.ego_known \
                    and indication(th, thresholds[2] + lookahead, cfg) is None:
                why += f": {ONLY_MAY_STAND}"
        elif levels[tid] > 0:
            why = f"{LEVEL_NAMES[levels[tid]]}, track {new_track} warned"
        else:
            why = blocked[tid]
        reasons[tid] = why + (", hidden" if th.coasted else "") \
            + ("" if th.ego_known else ", ego motion unknown")
    return new_state, events, report if level > 0 else None, reasons


def _extrapolated(last: TrackReport | None, elapsed: float) -> TrackReport | None:
    """The lost warned track as last seen, its TTC counted down; its distance is unknown."""
    if last is None:
        return None
    ttc = None if last.ttc_s is None else max(last.ttc_s - elapsed, 0.0)
    return replace(last, ttc_s=ttc, distance_m=None)
