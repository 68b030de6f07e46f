"""The run outputs of the spec, written in one place.

``warnings.jsonl``, ``tracks.jsonl``, ``egomotion.csv``, ``can_out.log`` and
``summary.json`` (spec: "What a run writes"). Rows are flushed as they are
written, so a run that is killed keeps everything up to that point.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import can
import numpy as np

from appliance import __version__
from appliance.code_digest import code_digest
from appliance.messages import EgoMotion, StepOutput, TrackReport, WarningEvent

EGOMOTION_HEADER = [
    "frame",
    "t",
    "epipole_u",
    "epipole_v",
    "rot_x",
    "rot_y",
    "rot_z",
    "prior_epipole_u",
    "prior_epipole_v",
    "prior_rot_x",
    "prior_rot_y",
    "prior_rot_z",
    "inliers",
]


def _num(x: float | None) -> float | None:
    """JSON-safe number: NaN/inf become null (spec: unknown quantities are null)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _bbox(b: Sequence[float] | None) -> list[float] | None:
    return None if b is None else [float(v) for v in b]


def track_row(tr: TrackReport) -> dict[str, Any]:
    row: dict[str, Any] = {
        "id": int(tr.id),
        "bbox": _bbox(tr.bbox),
        "probability": _num(tr.probability),
        "flow": [float(tr.flow[0]), float(tr.flow[1])],
        "ttc_s": _num(tr.ttc_s),
        "distance_m": _num(tr.distance_m),
    }
    if tr.reason is not None:
        row["reason"] = tr.reason
    return row


def warning_row(w: WarningEvent) -> dict[str, Any]:
    return {
        "t": float(w.t),
        "frame": int(w.frame),
        "level": int(w.level),
        "track": None if w.track is None else int(w.track),
        "bbox": _bbox(w.bbox),
        "ttc_s": _num(w.ttc_s),
        "distance_m": _num(w.distance_m),
        "bearing_rad": _num(w.bearing_rad),
    }


def egomotion_row(frame: int, t: float, ego: EgoMotion) -> list[str]:
    def fmt(x: float | None) -> str:
        return "" if x is None or not math.isfinite(float(x)) else repr(float(x))

    e = ego.epipole_px or (None, None)
    pe = ego.prior_epipole_px or (None, None)
    r = np.asarray(ego.rotation, float)
    pr = np.asarray(ego.prior_rotation, float)
    return [
        str(frame),
        repr(float(t)),
        fmt(e[0]),
        fmt(e[1]),
        fmt(r[0]),
        fmt(r[1]),
        fmt(r[2]),
        fmt(pe[0]),
        fmt(pe[1]),
        fmt(pr[0]),
        fmt(pr[1]),
        fmt(pr[2]),
        str(int(ego.inliers)),
    ]


def timing_stats(values_ms: Sequence[float]) -> dict[str, float | None]:
    """Median, p99 and max of a list of durations (ms); None when empty."""
    if not values_ms:
        return {"median": None, "p99": None, "max": None, "count": 0}
    a = np.asarray(values_ms, float)
    return {
        "median": round(float(np.median(a)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
        "count": int(a.size),
    }


class RunOutputs:
    """Writes a run's outputs into ``out_dir`` (created; existing output files are replaced).

    ``can_log=False`` leaves ``can_out.log`` to the live HMI writer, which logs every frame
    as it goes on the bus.
    """

    def __init__(self, out_dir: str | Path, can_log: bool = True) -> None:
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._warnings = (self.dir / "warnings.jsonl").open("w")
        self._tracks = (self.dir / "tracks.jsonl").open("w")
        self._ego_fh = (self.dir / "egomotion.csv").open("w", newline="")
        self._ego = csv.writer(self._ego_fh, lineterminator="\n")
        self._ego.writerow(EGOMOTION_HEADER)
        self._can = can.CanutilsLogWriter(str(self.dir / "can_out.log")) if can_log else None
        self.warnings_issued = 0
        self.can_frames = 0
        self._closed = False

    def write_step(self, out: StepOutput) -> None:
        """One processed frame: its egomotion row, its tracks row and any warning changes."""
        self._ego.writerow(egomotion_row(out.frame, out.t, out.ego))
        row = {
            "t": float(out.t),
            "frame": int(out.frame),
            "tracks": [track_row(tr) for tr in out.tracks],
        }
        self._tracks.write(json.dumps(row) + "\n")
        self.write_warnings(out.warnings)

    def write_warnings(self, events: Sequence[WarningEvent]) -> None:
        """Warning state changes (``warnings.jsonl``), flushed at once."""
        for w in events:
            self._warnings.write(json.dumps(warning_row(w)) + "\n")
            if w.level > 0:
                self.warnings_issued += 1
        self._warnings.flush()

    def write_can(self, msgs: Sequence[can.Message]) -> None:
        """Frames the appliance sent (``can_out.log``, candump -L)."""
        if self._can is None:
            raise RuntimeError("can_out.log belongs to the HMI writer in this run")
        for m in msgs:
            self._can.on_message_received(m)
            self.can_frames += 1

    def flush(self) -> None:
        self._warnings.flush()
        self._tracks.flush()
        self._ego_fh.flush()
        if self._can is not None:
            self._can.file.flush()

    def write_summary(self, summary: dict[str, Any]) -> Path:
        """``summary.json``; ``can_frames_sent`` counts ``can_out.log`` when this object writes
        it, else the caller gives it (the HMI writer's count)."""
        own = {"can_frames_sent": self.can_frames} if self._can is not None else {}
        if "can_frames_sent" not in {**own, **summary}:
            raise ValueError("summary.json needs can_frames_sent from the HMI writer")
        body = {
            "version": __version__,
            "code_digest": code_digest(),
            "warnings_issued": self.warnings_issued,
            **own,
            **summary,
        }
        path = self.dir / "summary.json"
        path.write_text(json.dumps(body, indent=2, sort_keys=True) + "\n")
        return path

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._warnings.close()
        self._tracks.close()
        self._ego_fh.close()
        if self._can is not None:
            self._can.stop()

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
