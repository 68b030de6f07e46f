"""Drive recordings with an input fault injected, written from a clean one.

A copy of a recording in which the vehicle CAN is silent (from ``can_until`` on, or from the
start), the PTU stops answering (from ``ptu_until`` on), or some frames are missing
(``keep_frame`` False: a camera outage, dropped frames). The simulator's truth is kept, so the
faulty drive is scored like the clean one.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from appliance.config import Config
from appliance.recording import Recording, RecordingWriter


def with_fault(src: Path, dst: Path, cfg: Config, *, can_until: float | None = None,
               ptu_until: float | None = None,
               keep_frame: Callable[[int, float], bool] | None = None) -> Path:
    """Copy ``src`` to ``dst`` with the fault: CAN frames only before ``can_until`` (s, on the
    recording clock; -inf: none at all), PTU samples only before ``ptu_until``, frames only
    where ``keep_frame(index, t)``."""
    rec = Recording(src, defaults=cfg)
    renumbered: dict[int, int] = {}   # frame index in src -> in dst
    with RecordingWriter(dst, rec.meta) as w:
        for frame in rec.frames():
            if keep_frame is None or keep_frame(frame.index, frame.t):
                renumbered[frame.index] = w.write_frame(frame.image, frame.t)
        for msg in rec.can_messages():
            if can_until is None or msg.timestamp < can_until:
                w.write_can(msg)
        ptu = rec.ptu()
        if ptu is not None:
            for t, pan, tilt in zip(ptu.t, ptu.pan, ptu.tilt):
                if ptu_until is None or t < ptu_until:
                    w.write_ptu(float(t), float(pan), float(tilt))
    truth = rec.truth()
    if truth is not None:
        (dst / "truth.json").write_text(json.dumps(_renumbered(truth, renumbered)))
    return dst


def _renumbered(truth: dict[str, Any], index: dict[int, int]) -> dict[str, Any]:
    """The truth with its per-frame entries (objects' frames, camera poses) of the kept frames
    only, under their new indices."""
    def frames(per_frame: dict[str, Any]) -> dict[str, Any]:
        return {str(index[int(k)]): v for k, v in per_frame.items() if int(k) in index}

    out = dict(truth)
    out["objects"] = [{**o, "frames": frames(o["frames"])} for o in truth["objects"]]
    if isinstance(truth.get("camera_poses"), dict):
        out["camera_poses"] = frames(truth["camera_poses"])
    return out
