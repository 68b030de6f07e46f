"""What kept a level 2 from being in time: the colliding object's frames before the target lead.

A level 2 is in time up to ``TARGETS["lead_time_s"]`` (1.5 s) before contact. Over the
``LATE_WINDOW_S`` before that (3.5-1.5 s before contact), each frame of the colliding object
is put in one class: the state of the track on it that came furthest through
``warnings.indication``'s checks (its ``reason`` in ``tracks.jsonl``, e.g. ``"probability 0.37
below 0.50"``), ``"no track"`` where no confirmed track was on it (a match, IoU >= 0.3, or a
track on part of it: its centre inside, or 80 % of it inside), or ``"hidden"`` where it was
less than half visible and no track was on it. Summed over runs, the classes say where the
time goes: detection (no track), the 3-D state (not moving over ground), the evidence
(probability), the prediction (path, TTC above the threshold).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from typing import Any

import numpy as np
from numpy.typing import NDArray

from appliance.config import MountConfig
from appliance.evaluation.metrics import (
    IOU_MATCH,
    MIN_VISIBLE,
    TARGETS,
    clip_box,
    colliding_object,
    iou,
    on_part_of,
)
from appliance.evaluation.runfiles import TrackRow, Truth, TruthObject

LATE_WINDOW_S = 2.0        # s before the target lead: the frames a level 2 would be in time
NO_TRACK = "no track"
HIDDEN = "hidden"

# (class, reason prefix), in the order of warnings.indication's checks from the last one back:
# a track that fails a later check came further than one failing an earlier one
KINDS: tuple[tuple[str, str], ...] = (
    ("warning", "warning"),
    ("caution, only may stand", "caution: only may stand"),
    ("caution", "caution"),
    ("ttc above threshold", "ttc "),
    ("no time to collision", "no time to collision"),
    ("path stays ahead", "path stays "),
    ("path misses corridor", "path "),
    ("probability", "probability "),
    ("box too low", "box "),
    ("standing, not closing", "standing:"),
    ("roadside", "stands at the roadside"),
    ("not moving over ground", "not moving over ground"),
)
ORDER = (*(k for k, _ in KINDS), "other", NO_TRACK, HIDDEN)


def kind(reason: str | None) -> str:
    """The class of a track's ``reason`` (``KINDS``; ``"other"`` for one not listed)."""
    for name, prefix in KINDS:
        if reason is not None and reason.startswith(prefix):
            return name
    return "other"


def late_reasons(o: TruthObject, ct: float, tracks: list[TrackRow],
                 frame_times: NDArray[np.float64], image_size: tuple[int, int]
                 ) -> dict[str, Any]:
    """``{"window_s": [from, to], "frames": n, "counts": {class: frames}}`` of object ``o``
    over the frames ``LATE_WINDOW_S`` before the target lead to the target lead before the
    contact at ``ct`` (module docstring); a frame without the object in its truth is not
    counted."""
    lead = TARGETS["lead_time_s"]
    width, height = image_size
    by_frame: dict[int, list[TrackRow]] = defaultdict(list)
    for tr in tracks:
        by_frame[tr.frame].append(tr)
    counts: Counter[str] = Counter()
    for f, t in enumerate(frame_times):
        if not lead <= ct - float(t) <= lead + LATE_WINDOW_S:
            continue
        i = o.at(f)
        if i is None:
            continue
        box = clip_box(o.bbox[i], width, height)
        kinds = [kind(tr.reason) for tr in by_frame.get(f, [])
                 if iou(tr.bbox, box) >= IOU_MATCH or on_part_of(tr.bbox, box)]
        if kinds:
            counts[min(kinds, key=ORDER.index)] += 1
        else:
            counts[HIDDEN if o.visible[i] < MIN_VISIBLE else NO_TRACK] += 1
    return {"window_s": [round(lead + LATE_WINDOW_S, 3), round(lead, 3)],
            "frames": sum(counts.values()),
            "counts": {k: counts[k] for k in ORDER if counts[k]}}


def explain_late(truth: Truth, tracks: list[TrackRow], frame_times: NDArray[np.float64],
                 image_size: tuple[int, int], mount: MountConfig) -> dict[str, Any] | None:
    """:func:`late_reasons` of the object a drive collides with; None without a collision."""
    o = colliding_object(truth, frame_times, mount)
    if o is None or truth.collision_t is None:
        return None
    return late_reasons(o, truth.collision_t, tracks, frame_times, image_size)


def pooled_counts(results: list[dict[str, Any]]) -> Counter[str]:
    """The classes' frames summed over results that have ``late_reasons``."""
    total: Counter[str] = Counter()
    for r in results:
        late = r.get("late_reasons")
        if late:
            total.update(late["counts"])
    return total


def describe(counts: dict[str, int] | Counter[str]) -> str:
    """``"no track 55 %, not moving over ground 13 %, ..."``, the largest first."""
    n = sum(counts.values())
    if n == 0:
        return "no frames"
    ranked = sorted(counts.items(), key=lambda kv: (-kv[1], ORDER.index(kv[0])))
    return ", ".join(f"{k} {100.0 * v / n:.0f} %" for k, v in ranked)
