"""Scores of one run against its recording's truth: detection delay, warning lead time, TTC and
distance errors.

Definitions (what a validation engineer expects):

* **Match:** a confirmed track matches a truth object in a frame when their boxes
  have IoU >= 0.3 (the truth box clipped to the image).
* **Eligible frames** of a mover: its truth box is at least 15 px tall inside the
  image, at least half of it is visible, and it moves over the ground (faster than
  0.3 m/s, the vision benchmark's rule): a pedestrian waiting at the kerb is
  "moving" in truth.json but not moving independently of the static scene, which
  is what the appliance detects. The ego motion that tells the two apart is the
  truth itself: a static object at p moves at ``(-v + w p_y, -w p_x)`` relative to
  the vehicle, so each frame's static object farthest ahead gives v and w. A frame
  without one (or a mover without ``vel_vehicle``) counts as moving.
* **First detection:** the first frame with a match; the delay is counted in
  frames from the first eligible frame (target: <= 10).
* **Tracked fraction:** eligible frames with a match / eligible frames.
* **Attribution:** a track id belongs to the object it matched in most frames
  (at least 3); a track that never matched a mover is a track on a static object
  or on nothing.
* **Colliding object:** ``collision_object`` of the truth when given, else the
  mover whose truth position is closest to the ego outline at ``collision_t``. A standing
  object named there (a car stopped in the lane) counts as a mover for the matches, the
  warnings and the errors below, but has no eligible frames (it never moves).
* **Lead time:** ``collision_t`` minus the first level-2 event on the colliding
  object at or before ``collision_t``; null when there was none (a missed
  warning). A warning is on an object when its box matches the object's truth
  box in that frame, or when its track is attributed to the object and matched
  it within 15 frames (0.5 s at 30 fps) of the warning, or within 15 frames before an
  occlusion (the object less than half visible) that lasts until the warning: a hidden
  object's coasted track cannot match it.
* **Caution lead time:** the same for the first event at level 1 or 2 on the colliding
  object (for a standing or braking lead car the first alert is judged: NHTSA's FCW
  confirmation tests want it at a TTC of at least 2.1-2.4 s).
* **False level-2 warnings:** level-2 onsets (a level-2 event after a lower
  level; a change of the track behind a continuing level 2 is not a new warning
  for the driver) in a no-collision scenario, or, in a collision scenario, not on
  a moving object. Besides the matches above, a warning is on a mover whose box
  holds at least 80 % of the warning's box while the mover is at least half visible
  (a close pedestrian warned on its legs' box: IoU 0.17, but not a static object).
* **Level-1 per minute:** onsets from level 0 to level >= 1 per minute of recording.
* **Ghost tracks:** confirmed tracks never on a mover in any frame of their life (a track is on
  a mover in a frame when their boxes match, when the track box's centre lies inside the
  mover's box, or when the mover's box holds at least 80 % of the track's): tracks on static
  scenery or on nothing. Reported as a count, their frames and a rate per minute of recording;
  no target counts them (the false-warning targets do), but a change that makes more of them
  makes more chances of a false warning.
* **Truth course of a level-1 onset:** what the truth says of the caution when it was
  raised: every mover's course continued at its truth velocity over the ground (the ego
  vehicle on its truth arc; a mover's speed keeps changing as it did over the last 6
  frames, so a braking car stops) for ``caution_s`` (``warning.ttc_caution_s``, 3 s), and the
  one that comes closest to the ego outline widened by ``margin_m`` on each side
  (``warning.corridor_margin_m``, 0.3 m): its id, when it meets that outline (null: it
  does not within the horizon) and its closest gap. A caution for a pedestrian walking
  into the path who stops later is right when it is raised; one on nothing is not. The
  count of onsets whose truth course meets the outline is reported; the level-1 target
  counts every onset.
* **TTC / distance error:** medians over the frames of the last 3 s before
  ``collision_t`` of |estimate - truth| / truth for the track of the colliding
  object; the truth TTC is ``collision_t - t``, the truth distance is the gap
  between the ego outline and the object's footprint (``gap_m``, what the
  appliance's ``distance_m`` is: the gap to the object's near side; recordings
  without it fall back to the footprint's centre ``pos_vehicle``). Frames closer
  than 0.2 s / 0.5 m are left out (the ratio is meaningless there);
  ``*_coverage`` is the fraction of the window's frames that had an estimate.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from typing import Any

import numpy as np
from numpy.typing import NDArray

from appliance.config import MountConfig
from appliance.decision.threat import predict_path
from appliance.evaluation.runfiles import Box, TrackRow, Truth, TruthObject, WarningRow

IOU_MATCH = 0.3
MIN_HEIGHT_PX = 15.0
MIN_VISIBLE = 0.5
DETECT_WITHIN_FRAMES = 10
LAST_WINDOW_S = 3.0
MIN_ATTRIBUTED_FRAMES = 3
ATTRIBUTION_WINDOW = 15  # frames
INSIDE_SHARE = 0.8       # a warning box this much inside a visible mover's box is on the mover
MIN_SPEED_M_S = 0.3      # a mover slower than this over the ground is standing, not eligible
COURSE_ACCEL_FRAMES = 6  # a truth course's acceleration: its speed's change over this many frames

TARGETS = {
    "lead_time_s": 1.5,
    "detect_frames": DETECT_WITHIN_FRAMES,
    "level1_per_min": 1.0,
    "ttc_rel_error": 0.20,
    "distance_rel_error": 0.15,
}


def _intersection(a: Box | NDArray[np.float64], b: Box | NDArray[np.float64]) -> float:
    """Area of the overlap of two (u0, v0, u1, v1) boxes (0 when they do not overlap)."""
    iw = min(a[2], b[2]) - max(a[0], b[0])
    ih = min(a[3], b[3]) - max(a[1], b[1])
    return float(iw * ih) if iw > 0 and ih > 0 else 0.0


def iou(a: Box | NDArray[np.float64], b: Box | NDArray[np.float64]) -> float:
    """Intersection over union of two (u0, v0, u1, v1) boxes."""
    inter = _intersection(a, b)
    if inter <= 0.0:
        return 0.0
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / union) if union > 0 else 0.0


def inside_share(a: Box | NDArray[np.float64], b: Box | NDArray[np.float64]) -> float:
    """Share of box a's area (u0, v0, u1, v1) inside box b (0 for an empty a)."""
    area = (a[2] - a[0]) * (a[3] - a[1])
    return float(_intersection(a, b) / area) if area > 0 else 0.0


def clip_box(b: NDArray[np.float64], width: int, height: int) -> NDArray[np.float64]:
    return np.array([max(b[0], 0.0), max(b[1], 0.0), min(b[2], float(width)),
                     min(b[3], float(height))])


def onsets(warnings: list[WarningRow]) -> tuple[list[WarningRow], list[WarningRow]]:
    """(level-2 onsets, level-1-or-higher onsets from 0), in time order."""
    l2, l1 = [], []
    prev_level = 0
    for w in sorted(warnings, key=lambda w: (w.t, w.frame)):
        if w.level == 2 and prev_level < 2:
            l2.append(w)
        if w.level >= 1 and prev_level == 0:
            l1.append(w)
        prev_level = w.level
    return l2, l1


def ego_motion(objects: tuple[TruthObject, ...] | list[TruthObject]
               ) -> dict[int, tuple[float, float]]:
    """Ego speed (m/s) and yaw rate (rad/s) per frame from the static truth objects.

    A static point at p = (p_x, p_y) moves at ``(-v + w p_y, -w p_x)`` relative to the
    vehicle (ISO 8855); per frame the static object farthest ahead (best conditioned for
    w) gives ``w = -vel_y / p_x`` and ``v = -vel_x + w p_y``.
    """
    best: dict[int, tuple[float, float, float]] = {}   # frame -> (|p_x|, v, w)
    for o in objects:
        if o.moving or o.vel is None:
            continue
        for f, (px, py), (vx, vy) in zip(o.frames, o.pos, o.vel, strict=True):
            if not (np.isfinite(px) and np.isfinite(py) and np.isfinite(vx) and np.isfinite(vy)):
                continue
            if abs(px) < 1.0 or abs(px) <= best.get(int(f), (0.0, 0.0, 0.0))[0]:
                continue
            w = -vy / px
            best[int(f)] = (abs(px), -vx + w * py, w)
    return {f: (v, w) for f, (_, v, w) in best.items()}


def _ground_velocity(o: TruthObject, i: int, speed: float, yaw: float
                     ) -> NDArray[np.float64] | None:
    """Row i's truth velocity over the ground (m/s, vehicle frame), the ego vehicle at ``speed``
    and ``yaw`` rate (:func:`ego_motion`'s inverse); None where position or velocity is unknown."""
    if o.vel is None or not np.all(np.isfinite(o.pos[i])) or not np.all(np.isfinite(o.vel[i])):
        return None
    (px, py), (vx, vy) = o.pos[i], o.vel[i]
    return np.array([vx - (-speed + yaw * py), vy - (-yaw * px)])


def ground_speed(o: TruthObject, ego: dict[int, tuple[float, float]]) -> NDArray[np.float64]:
    """(N,) speed of a truth object over the ground per frame, m/s; NaN where unknown."""
    out = np.full(len(o.frames), np.nan)
    for i, f in enumerate(o.frames):
        e = ego.get(int(f))
        g = None if e is None else _ground_velocity(o, i, *e)
        if g is not None:
            out[i] = math.hypot(g[0], g[1])
    return out


def eligible_mask(o: TruthObject, ego: dict[int, tuple[float, float]], width: int,
                  height: int) -> NDArray[np.bool_]:
    """(N,) the object's eligible frames (module docstring): at least 15 px tall inside the
    image, at least half visible, moving over the ground. ``ego``: :func:`ego_motion`."""
    clipped = np.array([clip_box(b, width, height) for b in o.bbox]).reshape(-1, 4)
    tall = (clipped[:, 3] - clipped[:, 1]) >= MIN_HEIGHT_PX
    wide = (clipped[:, 2] - clipped[:, 0]) > 0
    moving = ~(ground_speed(o, ego) <= MIN_SPEED_M_S)          # NaN (unknown): counts as moving
    mask: NDArray[np.bool_] = tall & wide & (o.visible >= MIN_VISIBLE) & moving
    return mask


def truth_course(movers: list[TruthObject], frame: int, ego: dict[int, tuple[float, float]],
                 frame_times: NDArray[np.float64], mount: MountConfig, margin_m: float,
                 caution_s: float) -> tuple[int | None, float | None, float | None]:
    """(id, time to meet the widened outline or None, closest gap m) of the mover whose
    course from ``frame`` comes closest (module docstring): continued at its truth velocity
    and its speed's change over the last ``COURSE_ACCEL_FRAMES`` (a braking car stops);
    (None, None, None) when no mover has a position and velocity then."""
    best: tuple[int | None, float | None, float | None] = (None, None, None)
    best_key = (2, 0.0)
    k = frame - COURSE_ACCEL_FRAMES
    speed, yaw = ego.get(frame, (0.0, 0.0))   # unknown: the relative velocity, in the vehicle frame
    for o in movers:
        i = o.at(frame)
        ground = None if i is None else _ground_velocity(o, i, speed, yaw)
        if i is None or ground is None:
            continue
        accel = 0.0
        j = o.at(k)
        before = None if j is None else _ground_velocity(o, j, *ego.get(k, (0.0, 0.0)))
        if before is not None and 0 <= k and frame < len(frame_times) \
                and frame_times[frame] > frame_times[k]:
            dt = float(frame_times[frame] - frame_times[k])
            accel = (math.hypot(*ground) - math.hypot(*before)) / dt
        path = predict_path(o.pos[i], ground, speed, yaw, mount, margin_m, 0.0, caution_s, accel)
        key = (0, path.ttc) if path.ttc is not None else (1, path.closest)   # soonest, else nearest
        if key < best_key:
            best, best_key = (o.id, path.ttc, round(path.closest, 2)), key
    return best


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def evaluate(truth: Truth, tracks: list[TrackRow], warnings: list[WarningRow],
             frame_times: NDArray[np.float64], image_size: tuple[int, int],
             mount: MountConfig, margin_m: float = 0.3, caution_s: float = 3.0) -> dict[str, Any]:
    """All scores of one run as a JSON-ready dict (see the module docstring); ``margin_m``
    and ``caution_s``: the corridor margin and level-1 horizon of the truth courses."""
    width, height = image_size
    n_frames = len(frame_times)
    duration_s = float(frame_times[-1] - frame_times[0]) if n_frames > 1 else 0.0
    by_frame: dict[int, list[TrackRow]] = defaultdict(list)
    for tr in tracks:
        by_frame[tr.frame].append(tr)
    movers = [o for o in truth.objects if o.moving]
    ego = ego_motion(truth.objects)
    # a standing object the drive collides with (a car stopped in the lane) is scored like a
    # mover for the warnings, TTC and distance, but has no detection delay (it never moves)
    standing = [o for o in truth.objects if not o.moving and truth.collision
                and o.id == truth.collision_object]
    scored = movers + standing

    # per frame, the best-matching track of every mover; attribution of track ids; the
    # tracks that were ever on a mover (the others are ghosts)
    match: dict[int, dict[int, TrackRow]] = {o.id: {} for o in scored}
    votes: dict[int, Counter[int]] = defaultdict(Counter)
    on_mover: set[int] = set()
    for o in scored:
        for i, f in enumerate(o.frames):
            box = clip_box(o.bbox[i], width, height)
            best, best_iou = None, IOU_MATCH
            for tr in by_frame.get(int(f), []):
                v = iou(tr.bbox, box)
                if v >= best_iou:
                    best, best_iou = tr, v
                if v >= IOU_MATCH or on_part_of(tr.bbox, box):
                    on_mover.add(tr.id)
            if best is not None:
                match[o.id][int(f)] = best
                votes[best.id][o.id] += 1
    track_frames = Counter(tr.id for tr in tracks)
    ghosts = [tid for tid in track_frames if tid not in on_mover]
    ghost_frames = sum(track_frames[tid] for tid in ghosts)
    owner: dict[int, int] = {}
    for tid, c in votes.items():
        oid, n = c.most_common(1)[0]
        if n >= MIN_ATTRIBUTED_FRAMES:
            owner[tid] = oid

    objects_out: list[dict[str, Any]] = []
    delays: list[int | None] = []
    for o in movers:
        eligible = o.frames[eligible_mask(o, ego, width, height)]
        matched = sorted(match[o.id])
        first_eligible = int(eligible[0]) if len(eligible) else None
        first_det = int(matched[0]) if matched else None
        delay = (None if first_eligible is None or first_det is None
                 else max(first_det - first_eligible, 0))
        tracked = (float(np.mean([int(f) in match[o.id] for f in eligible]))
                   if len(eligible) else None)
        delays.append(delay)
        objects_out.append({
            "id": o.id, "class": o.cls, "eligible_frames": len(eligible),
            "first_eligible_frame": first_eligible, "first_detection_frame": first_det,
            "detection_delay_frames": delay, "tracked_fraction": tracked,
            "track_ids": sorted(t for t, oid in owner.items() if oid == o.id),
        })

    l2_onsets, l1_onsets = onsets(warnings)
    ct = truth.collision_t if truth.collision else None
    colliding = colliding_object(truth, frame_times, mount)

    def on_object(w: WarningRow, o: TruthObject) -> bool:
        # the warning's box matches the object then, or its track matched the object within
        # ATTRIBUTION_WINDOW frames (a track that switched objects does not count)
        i = o.at(w.frame)
        if w.bbox is not None and i is not None:
            box = clip_box(o.bbox[i], width, height)
            if iou(w.bbox, box) >= IOU_MATCH:
                return True
            # a box on part of the object (its legs, close up) is still on it, not on the scene
            if o.visible[i] >= MIN_VISIBLE and inside_share(w.bbox, box) >= INSIDE_SHARE:
                return True
        if w.track is None or owner.get(w.track) != o.id:
            return False

        def matched_in(frames: range) -> bool:
            return any(f in match[o.id] and match[o.id][f].id == w.track for f in frames)

        if matched_in(range(w.frame - ATTRIBUTION_WINDOW, w.frame + ATTRIBUTION_WINDOW + 1)):
            return True
        # the object's own track, warning while the object is hidden: the track matched it
        # within ATTRIBUTION_WINDOW frames before an occlusion (less than half visible) that
        # lasts until the warning (a hidden object's coasted track cannot match it)
        i = o.at(w.frame)
        if i is None or o.visible[i] >= MIN_VISIBLE:
            return False
        shown = np.flatnonzero((o.visible >= MIN_VISIBLE) & (o.frames < w.frame))
        hidden_from = int(o.frames[shown[-1]]) + 1 if len(shown) else int(o.frames[0])
        return matched_in(range(hidden_from - ATTRIBUTION_WINDOW, hidden_from))

    if truth.collision:
        false_l2 = [w for w in l2_onsets if not any(on_object(w, o) for o in scored)]
    else:
        false_l2 = list(l2_onsets)
    # every warning event on the colliding object up to contact, in time order; a switch of a
    # continuing warning to its track counts too
    on_colliding = [] if colliding is None or ct is None else [
        w for w in sorted(warnings, key=lambda w: w.t)
        if w.level >= 1 and w.t <= ct + 1e-6 and on_object(w, colliding)]
    first_l2_t = next((w.t for w in on_colliding if w.level == 2), None)
    first_l1_t = on_colliding[0].t if on_colliding else None
    lead = None if first_l2_t is None or ct is None else ct - first_l2_t
    caution_lead = None if first_l1_t is None or ct is None else ct - first_l1_t

    ttc_err, dist_err, ttc_cov, dist_cov = _last_window_errors(
        colliding, ct, match, owner, by_frame, frame_times, mount) if colliding is not None \
        and ct is not None else (None, None, None, None)

    courses: list[dict[str, Any]] = []
    for w in l1_onsets:
        who, meets, closest = truth_course(movers, w.frame, ego, frame_times, mount, margin_m,
                                           caution_s)
        courses.append({"t": round(w.t, 3), "frame": w.frame, "object": who,
                        "truth_meets_s": meets, "truth_closest_m": closest})

    minutes = duration_s / 60.0
    known = [d for d in delays if d is not None]
    worst_delay = None if not delays or len(known) < len(delays) else max(known)
    result: dict[str, Any] = {
        "scenario": truth.scenario,
        "collision": truth.collision,
        "collision_t": ct,
        "frames": n_frames,
        "duration_s": round(duration_s, 3),
        "objects": objects_out,
        "colliding_object": None if colliding is None else colliding.id,
        "first_level2_t": first_l2_t,
        "lead_time_s": None if lead is None else round(lead, 3),
        "first_level1_t": first_l1_t,
        "caution_lead_s": None if caution_lead is None else round(caution_lead, 3),
        "level2_onsets": len(l2_onsets),
        "false_level2": len(false_l2),
        "false_level2_t": [round(w.t, 3) for w in false_l2],
        "level1_onsets": len(l1_onsets),
        "level1_per_min": round(len(l1_onsets) / minutes, 3) if minutes > 0 else None,
        "level1_on_truth_course": sum(1 for c in courses if c["truth_meets_s"] is not None),
        "level1_courses": courses,
        "ghost_tracks": len(ghosts),
        "ghost_track_frames": ghost_frames,
        "ghost_tracks_per_min": round(len(ghosts) / minutes, 3) if minutes > 0 else None,
        "worst_detection_delay_frames": worst_delay,
        "ttc_rel_error_median": ttc_err,
        "ttc_coverage": ttc_cov,
        "distance_rel_error_median": dist_err,
        "distance_coverage": dist_cov,
    }
    result["targets"] = check_targets(result)
    return result


def on_part_of(track: Box, mover: NDArray[np.float64]) -> bool:
    """A track box on part of a mover's box without matching it (ghost tracks, module
    docstring): its centre inside, or at least ``INSIDE_SHARE`` of it inside."""
    cu, cv = 0.5 * (track[0] + track[2]), 0.5 * (track[1] + track[3])
    return (bool(mover[0] <= cu <= mover[2] and mover[1] <= cv <= mover[3])
            or inside_share(track, mover) >= INSIDE_SHARE)


def check_targets(r: dict[str, Any]) -> dict[str, bool | None]:
    """Pass/fail of the validation targets for one scenario (None: does not apply)."""
    coll = bool(r["collision"])
    lead = r["lead_time_s"]
    d = r["worst_detection_delay_frames"]
    def within(key: str, target: str) -> bool:
        return r[key] is not None and r[key] <= TARGETS[target]

    l1 = r["level1_per_min"]
    return {
        "lead_time": (lead is not None and lead >= TARGETS["lead_time_s"]) if coll else None,
        "no_false_level2": r["false_level2"] == 0,
        "level1_rate": None if coll else (l1 is None or l1 <= TARGETS["level1_per_min"]),
        "detection": None if not r["objects"] else (d is not None
                                                    and d <= TARGETS["detect_frames"]),
        "ttc_error": within("ttc_rel_error_median", "ttc_rel_error") if coll else None,
        "distance_error": within("distance_rel_error_median", "distance_rel_error")
        if coll else None,
    }


def _frame_at(frame_times: NDArray[np.float64], t: float) -> int:
    return int(np.clip(np.searchsorted(frame_times, t), 0, len(frame_times) - 1))


def colliding_object(truth: Truth, frame_times: NDArray[np.float64], mount: MountConfig
                     ) -> TruthObject | None:
    """The object the drive collides with (module docstring), None without a collision."""
    ct = truth.collision_t if truth.collision else None
    if ct is None:
        return None
    named = [o for o in truth.objects if o.id == truth.collision_object]
    if named:
        return named[0]
    movers = [o for o in truth.objects if o.moving]
    if not movers:
        return None
    f = _frame_at(frame_times, ct)
    best, best_gap = movers[0], math.inf
    for o in movers:
        ok = np.flatnonzero(np.all(np.isfinite(o.pos), axis=1))
        if len(ok) == 0:
            continue
        i = ok[np.argmin(np.abs(o.frames[ok] - f))]
        gap = float(o.gap_m(i, mount)[0])
        if gap < best_gap:
            best, best_gap = o, gap
    return best


def _last_window_errors(o: TruthObject, ct: float, match: dict[int, dict[int, TrackRow]],
                        owner: dict[int, int], by_frame: dict[int, list[TrackRow]],
                        frame_times: NDArray[np.float64], mount: MountConfig
                        ) -> tuple[float | None, float | None, float | None, float | None]:
    ttc_err: list[float] = []
    dist_err: list[float] = []
    n_ttc = n_dist = n_win = 0
    for f, t in enumerate(frame_times):
        remaining = ct - float(t)
        if not 0.0 < remaining <= LAST_WINDOW_S:
            continue
        n_win += 1
        tr = match[o.id].get(f)
        if tr is None:  # the attributed track, e.g. when the box left the image
            own = [r for r in by_frame.get(f, []) if owner.get(r.id) == o.id]
            tr = own[0] if own else None
        if tr is None:
            continue
        if tr.ttc_s is not None:
            n_ttc += 1
            if remaining >= 0.2:
                ttc_err.append(abs(tr.ttc_s - remaining) / remaining)
        i = o.at(f)
        if tr.distance_m is not None and i is not None and np.all(np.isfinite(o.pos[i])):
            n_dist += 1
            d_true = float(o.gap_m(i, mount)[0])
            if d_true >= 0.5:
                dist_err.append(abs(tr.distance_m - d_true) / d_true)
    def cov(n: int) -> float | None:
        return round(n / n_win, 3) if n_win else None

    med_t, med_d = _median(ttc_err), _median(dist_err)
    return (None if med_t is None else round(med_t, 4), None if med_d is None else round(med_d, 4),
            cov(n_ttc), cov(n_dist))
