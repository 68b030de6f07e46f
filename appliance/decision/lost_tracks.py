"""Tracks hidden by an occlusion (e.g. a parked car, the paper's fig. 7), kept as 3-D states.

A confirmed track the image tracker drops while it moves over ground becomes a
:class:`LostTrack`: its 3-D state coasts at constant velocity over ground (ego motion
removed) for ``hidden.keep_s``; a new track whose first ground contact falls in its
gate continues it under its id (:func:`reacquire`). For ``hidden.warn_s`` it is
also assessed from the coasted state (:func:`coasted_track`) while something nearer covers
it (:meth:`LostTrack.covered`) and until its head, where it shows above the occluder, is seen
off the coasted course (:meth:`LostTrack.with_course`; occlusion.py). It also keeps where it
would stand had it stopped when lost (``halted``); seen standing there (halted.py), or
continued there by an obstacle of the parallax cue (handover.py), it is kept for ``keep_s``
after it was last seen so.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from appliance.config import HiddenConfig
from appliance.decision.cues import TrackCues
from appliance.decision.ground_state import (
    CameraPose,
    GroundContact,
    GroundModel,
    ego_step,
    ground_in_camera,
    ground_predict,
    innovation_sigmas,
)
from appliance.decision.tracking import ImageTrack, TrackerState
from appliance.messages import SensorSample
from appliance.vision.geometry import FloatArray, PinholeCamera

REACQUIRE_GATE_SIGMAS = 3.0  # a new track continues a lost one whose coasted position is this close
REACQUIRE_GATE_M = 5.0       #   (Mahalanobis) and at most this far (m), whichever is tighter
COVER_RATIO = 1.15           # covered: the median cover ratio (occlusion.cover_ratio) is at least this
COVER_FRAMES = 5             # frames of that median, and of the head band's counts
COURSE_POINTS = 3            # head seen on course: the median count of its band's low-flow points is at
COURSE_FRACTION = 0.25       #   least this, and this share of its highest median so far
COURSE_SEEN_POINTS = 8       # ... and it counts as seen there only from this median on (background
                             #   alone counts 3-6)
HALT_FRAMES = 3              # seen standing where it stopped: the median of this many halt counts
HALT_POINTS = 6.0            #   (halted.halt_count) reaches this


@dataclass(frozen=True)
class LostTrack:
    """A confirmed track the image tracker lost while its 3-D state showed independent motion
    (an occlusion, e.g. by a parked car): its public id and cues, the 3-D state coasting at
    constant velocity over ground until a new track's first ground contact continues it or
    ``hidden.keep_s`` has passed since its last contact."""

    id: int
    cues: TrackCues
    track: ImageTrack | None = None  # the image track when it was lost (size, probability)
    cover: tuple[float, ...] = ()    # its last cover ratios (occlusion.cover_ratio; NaN: not measured)
    course: tuple[float, ...] = ()   # its head band's last counts (occlusion.coasted_course; NaN: not measured)
    seen_on_course: bool = False     # its head was seen keeping its bearing while hidden
    course_peak: float = 0.0         # the highest median count so far
    off_course: bool = False         # latched once its head, seen on course, was no longer
    halted: FloatArray | None = None  # (2,) m, current vehicle frame: where it would stand had it
                                      #   stopped when lost (its last position, moved with the ego)
    standing_seen: float | None = None  # s, when it was last seen standing where it stopped
                                        #   (halted.py), or an obstacle there continued it
    continued: bool = False             # an obstacle standing there continued it (handover.py):
                                        #   it is no longer coasted
    halt: tuple[float, ...] = ()        # its last halt counts (halted.halt_count; NaN: not measured)

    def covered(self) -> bool:
        """Whether something nearer hides it: the median of its last ``COVER_FRAMES``
        measured cover ratios is at least ``COVER_RATIO``."""
        last = np.asarray(self.cover[-COVER_FRAMES:], dtype=np.float64)
        last = last[np.isfinite(last)]
        return bool(last.size) and float(np.median(last)) >= COVER_RATIO

    def stands(self) -> bool:
        """Whether it is seen standing where it stopped: the median of its last
        ``HALT_FRAMES`` halt counts (halted.py), all measured, reaches ``HALT_POINTS``."""
        last = np.asarray(self.halt[-HALT_FRAMES:], dtype=np.float64)
        return last.size == HALT_FRAMES and bool(np.all(np.isfinite(last))) \
            and float(np.median(last)) >= HALT_POINTS

    def with_course(self, count: float) -> LostTrack:
        """This lost track with one more head-band count (``occlusion.course_count``).

        While the median of its last ``COVER_FRAMES`` measured counts is at least
        ``COURSE_POINTS`` and ``COURSE_FRACTION`` of its highest median so far (a
        head seen closer covers more points), its head keeps its bearing above the occluder;
        it counts as seen there once the median also reaches ``COURSE_SEEN_POINTS`` (a
        few points of background alone count 3-6). Once it was seen, and the median then
        falls below the first bar, the track is off course for good: what showed of it
        stopped keeping its bearing (a pedestrian who stopped behind a parked car), and its
        coasted state, which cannot see that, is no longer assessed. A track whose head was
        never seen (an occluder taller than it, or too far to count above the background)
        coasts as before."""
        course = (*self.course[1 - COVER_FRAMES:], count)
        last = np.asarray(course, dtype=np.float64)
        last = last[np.isfinite(last)]
        if last.size < COVER_FRAMES:
            return replace(self, course=course)
        median = float(np.median(last))
        on = median >= max(COURSE_POINTS, COURSE_FRACTION * self.course_peak)
        # seen at all only above what background in the band counts on its own (3-6 points)
        seen = on and median >= COURSE_SEEN_POINTS
        return replace(self, course=course, seen_on_course=self.seen_on_course or seen,
                       off_course=self.off_course or (self.seen_on_course and not on),
                       course_peak=max(self.course_peak, median))


def reacquire(lost: tuple[LostTrack, ...], contact: GroundContact) -> LostTrack | None:
    """The lost track whose coasted position is nearest (Mahalanobis) to ``contact``, inside
    ``REACQUIRE_GATE_SIGMAS`` and ``REACQUIRE_GATE_M``; None when none is."""
    best: tuple[float, LostTrack] | None = None
    for lt in lost:
        g = lt.cues.ground
        if g is None:
            continue
        m = innovation_sigmas(g, contact)
        far = float(np.hypot(*(contact.z - g.position)))
        if m <= REACQUIRE_GATE_SIGMAS and far <= REACQUIRE_GATE_M \
                and (best is None or m < best[0]):
            best = (m, lt)
    return best[1] if best is not None else None


def moved_within(cues: TrackCues, t: float, window: float) -> bool:
    """Whether a track has moved over ground (its motion cue) within ``window`` s before ``t``."""
    motion = cues.get("motion")
    return motion is not None and t - motion.t <= window


def coast_lost(previous: TrackerState, previous_cues: dict[int, TrackCues],
               previous_lost: tuple[LostTrack, ...], tracker: TrackerState, t: float, dt: float,
               sensors: SensorSample, model: GroundModel, cfg: HiddenConfig
               ) -> tuple[LostTrack, ...]:
    """The lost tracks after this frame: the previous ones and the confirmed tracks the image
    tracker dropped this frame while moving over ground, their 3-D states predicted by ``dt``
    (ego motion removed) and forgotten ``keep_s`` after their last ground contact."""
    if cfg.keep_s <= 0.0:
        return ()
    alive = {tr.uid for tr in tracker.tracks}
    dropped = tuple(LostTrack(id=int(tr.id), cues=previous_cues[tr.uid], track=tr)
                    for tr in previous.tracks
                    if tr.id is not None and tr.uid not in alive and tr.uid in previous_cues
                    and previous_cues[tr.uid].ground is not None
                    and moved_within(previous_cues[tr.uid], t, cfg.keep_s))
    # where each would stand had it stopped when it was lost: its last position
    dropped = tuple(replace(lt, halted=lt.cues.ground.position.copy())  # type: ignore[union-attr]
                    for lt in dropped)
    # no fading memory while coasting: it would inflate the covariance and widen the gate
    coasting = replace(model, memory_s=0.0)
    out: list[LostTrack] = []
    for lt in previous_lost + dropped:
        g = lt.cues.ground
        assert g is not None
        g = ground_predict(g, dt, sensors, coasting, steady=True)
        last = g.t_update if lt.standing_seen is None else max(g.t_update, lt.standing_seen)
        if t - last <= cfg.keep_s:
            out.append(replace(lt, cues=TrackCues(ground=g, states=lt.cues.states),
                               halted=halted_step(lt.halted, dt, sensors)))
    return tuple(out)


def halted_step(p: FloatArray | None, dt: float, sensors: SensorSample) -> FloatArray | None:
    """A static point's position (2,) m in the vehicle frame after the ego moved ``dt`` s
    (CAN speed and yaw rate): ``p' = Rt (p - d)`` (``ground_predict`` at zero velocity)."""
    if p is None or dt <= 0.0:
        return p
    speed = sensors.speed_m_s if np.isfinite(sensors.speed_m_s) else 0.0
    yaw = sensors.yaw_rate_rad_s if np.isfinite(sensors.yaw_rate_rad_s) else 0.0
    Rt, d = ego_step(speed, yaw, dt)
    return np.asarray(Rt @ (p - d), dtype=np.float64)


def coasted_foot(lt: LostTrack, pose: CameraPose) -> FloatArray | None:
    """The coasted ground position (3,) in the current camera frame (m; z: depth), or None."""
    g = lt.cues.ground
    return None if g is None else ground_in_camera(pose, g.position)


def coasted_track(lt: LostTrack, t: float, pose: CameraPose, x_m: float, camera: PinholeCamera,
                  warn_s: float) -> ImageTrack | None:
    """A lost (hidden) track as an image track from its coasted 3-D state, to be assessed like
    a seen one (with its cues, the scale cue left out: nothing of the object is measured), for
    ``warn_s`` after its last ground contact; None after that or when it cannot be placed in
    the image. ``x_m``: the camera's position along the vehicle's x axis (m).

    Its box is the last image box, scaled by the change of depth and centred above the
    coasted ground position projected into the image. What this cannot know is exactly what
    the occlusion hides: whether the object keeps its velocity; a pedestrian who stops behind
    the occluder is still predicted to walk on.
    """
    g, tr = lt.cues.ground, lt.track
    if g is None or tr is None or t - g.t_update > warn_s or lt.continued:
        return None
    depth_now = float(g.x[0] - x_m)
    depth_state = lt.cues.get("depth")
    depth_then = depth_state.depth if depth_state is not None else None
    if depth_now <= 0.5 or depth_then is None or depth_then <= 0.5:
        return None
    foot = coasted_foot(lt, pose)
    if foot is None or foot[2] <= 0.5:
        return None
    uf, vf = (float(c) for c in camera.project(foot[None])[0])
    k = depth_then / depth_now
    w, h = tr.size[0] * k, tr.size[1] * k
    x = tr.x.copy()
    x[0, 0], x[1, 0] = uf, vf - 0.5 * h
    x[:, 1:] = 0.0
    # the probability it had while seen: an occluder thins its region out before it is lost
    peaks = lt.cues.get("peaks")
    peak = peaks.probability if peaks is not None else 0.0
    return replace(tr, x=x, size=(w, h), cluster=None, probability=max(tr.probability, peak))
