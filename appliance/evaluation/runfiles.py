"""Read what ``evaluate`` compares: a run's ``tracks.jsonl``/``warnings.jsonl`` and ``truth.json``.

Every problem is a :class:`~appliance.errors.UsageError` naming the file, the line
and what is wrong (exit status 2, one line).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from appliance.config import MountConfig
from appliance.decision.threat import outline_gap
from appliance.errors import UsageError

Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class TrackRow:
    """One confirmed track in one frame (tracks.jsonl)."""

    frame: int
    t: float
    id: int
    bbox: Box
    ttc_s: float | None
    distance_m: float | None
    reason: str | None = None


@dataclass(frozen=True)
class WarningRow:
    """One warning state change (warnings.jsonl)."""

    t: float
    frame: int
    level: int
    track: int | None
    bbox: Box | None
    ttc_s: float | None


@dataclass(frozen=True)
class TruthObject:
    """One simulated object: per-frame box (px), visible fraction, position in the vehicle frame."""

    id: int
    cls: str
    moving: bool
    frames: NDArray[np.int64]
    bbox: NDArray[np.float64]  # (N, 4)
    visible: NDArray[np.float64]  # (N,)
    pos: NDArray[np.float64]  # (N, 2), NaN where unknown
    vel: NDArray[np.float64] | None = None  # (N, 2) m/s relative to the ego vehicle, NaN unknown
    gap: NDArray[np.float64] | None = None  # (N,) m footprint to ego outline (``gap_m``), NaN unknown

    def gap_m(self, rows: NDArray[np.int64] | int, mount: MountConfig) -> NDArray[np.float64]:
        """True distance (m) to the ego outline at row(s) ``rows``, as the appliance's
        ``distance_m`` means it: the footprint's ``gap_m`` where the truth has it, else the
        gap of the footprint's centre ``pos_vehicle`` (recordings without ``gap_m``; for a
        car ahead that is half its length too far)."""
        idx = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        centre = outline_gap(self.pos[idx], mount, 0.0)
        if self.gap is None:
            return np.asarray(centre, dtype=np.float64)
        g = self.gap[idx]
        return np.where(np.isfinite(g), g, centre)

    def at(self, frame: int) -> int | None:
        """Row index of ``frame`` or None."""
        i = int(np.searchsorted(self.frames, frame))
        return i if i < len(self.frames) and self.frames[i] == frame else None


@dataclass(frozen=True)
class Truth:
    scenario: str
    collision: bool
    collision_t: float | None
    objects: tuple[TruthObject, ...]
    collision_object: int | None = None  # optional: the id of the colliding object
    camera_frames: NDArray[np.int64] | None = None  # (F,) frames with a camera pose
    camera_centres: NDArray[np.float64] | None = None  # (F, 3) camera centre in the world, m


def _num(v: Any, where: str, key: str, *, optional: bool = True) -> float | None:
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise UsageError(f"{where}: {key} must be a finite number, got {v!r}")
    return float(v)


def _box(v: Any, where: str, key: str) -> Box:
    if not isinstance(v, list) or len(v) != 4:
        raise UsageError(f"{where}: {key} must be [u0, v0, u1, v1], got {v!r}")
    b = [_num(x, where, key, optional=False) for x in v]
    return (b[0], b[1], b[2], b[3])  # type: ignore[return-value]


def json_rows(path: Path) -> list[tuple[int, dict[str, Any]]]:
    """(line number, object) of each non-empty line of a JSON-lines file; a missing file or a
    bad line is a ``UsageError`` naming the file and the line."""
    if not path.is_file():
        raise UsageError(f"{path}: missing (is this the output directory of a replay or run?)")
    rows = []
    with path.open() as fh:
        for n, text in enumerate(fh, start=1):
            if not text.strip():
                continue
            try:
                obj = json.loads(text)
            except json.JSONDecodeError as exc:
                raise UsageError(f"{path}:{n}: invalid JSON ({exc.msg})") from None
            if not isinstance(obj, dict):
                raise UsageError(f"{path}:{n}: expected a JSON object")
            rows.append((n, obj))
    return rows


def read_tracks(path: Path) -> list[TrackRow]:
    out: list[TrackRow] = []
    for n, row in json_rows(path):
        where = f"{path}:{n}"
        try:
            frame, tracks = int(row["frame"]), row["tracks"]
            t = _num(row["t"], where, "t", optional=False)
        except (KeyError, TypeError, ValueError):
            raise UsageError(f"{where}: needs frame, t and tracks") from None
        if not isinstance(tracks, list):
            raise UsageError(f"{where}: tracks must be a list")
        for tr in tracks:
            if not isinstance(tr, dict) or "id" not in tr or "bbox" not in tr:
                raise UsageError(f"{where}: every track needs id and bbox")
            out.append(TrackRow(frame=frame, t=float(t), id=int(tr["id"]),  # type: ignore[arg-type]
                                bbox=_box(tr["bbox"], where, "bbox"),
                                ttc_s=_num(tr.get("ttc_s"), where, "ttc_s"),
                                distance_m=_num(tr.get("distance_m"), where, "distance_m"),
                                reason=tr["reason"] if isinstance(tr.get("reason"), str)
                                else None))
    return out


def read_warnings(path: Path) -> list[WarningRow]:
    out: list[WarningRow] = []
    for n, row in json_rows(path):
        where = f"{path}:{n}"
        try:
            level = int(row["level"])
            t = _num(row["t"], where, "t", optional=False)
            frame = int(row["frame"])
        except (KeyError, TypeError, ValueError):
            raise UsageError(f"{where}: needs t, frame and level") from None
        if level not in (0, 1, 2):
            raise UsageError(f"{where}: level must be 0, 1 or 2, got {level}")
        bbox = row.get("bbox")
        track = row.get("track")
        out.append(WarningRow(t=float(t), frame=frame, level=level,  # type: ignore[arg-type]
                              track=None if track is None else int(track),
                              bbox=None if bbox is None else _box(bbox, where, "bbox"),
                              ttc_s=_num(row.get("ttc_s"), where, "ttc_s")))
    return out


def parse_truth(data: dict[str, Any], where: str) -> Truth:
    """``truth.json`` (spec) -> :class:`Truth`; missing or malformed keys name the key."""
    try:
        collision = bool(data["collision"])
        objects_raw = data["objects"]
    except KeyError as exc:
        raise UsageError(f"{where}: missing key {exc.args[0]!r}") from None
    ct = _num(data.get("collision_t"), where, "collision_t")
    if collision and ct is None:
        raise UsageError(f"{where}: collision is true but collision_t is null")
    objects = []
    for k, obj in enumerate(objects_raw):
        key = f"objects[{k}]"
        if not isinstance(obj, dict) or not isinstance(obj.get("frames"), dict):
            raise UsageError(f"{where}: {key} needs a frames table")
        items = sorted(((int(f), v) for f, v in obj["frames"].items()), key=lambda kv: kv[0])
        frames = np.array([f for f, _ in items], dtype=np.int64)
        bbox = np.array([_box(v.get("bbox"), where, f"{key}.frames.{f}.bbox") for f, v in items],
                        dtype=np.float64).reshape(-1, 4)
        visible = np.array([_num(v.get("visible", 1.0), where, f"{key}.visible", optional=False)
                            for _, v in items], dtype=np.float64)
        pos = _vectors(items, "pos_vehicle", where, key)
        vel = _vectors(items, "vel_vehicle", where, key)
        gap = np.array([np.nan if v.get("gap_m") is None else
                        _num(v.get("gap_m"), where, f"{key}.frames.{f}.gap_m", optional=False)
                        for f, v in items], dtype=np.float64)
        objects.append(TruthObject(id=int(obj.get("id", k)), cls=str(obj.get("class", "object")),
                                   moving=bool(obj.get("moving", True)), frames=frames, bbox=bbox,
                                   visible=visible, pos=pos, vel=vel, gap=gap))
    co = data.get("collision_object")
    cam_frames, centres = _camera_centres(data.get("camera_poses"), where)
    return Truth(scenario=str(data.get("scenario", "?")), collision=collision, collision_t=ct,
                 objects=tuple(objects),
                 collision_object=int(co) if isinstance(co, int) and not isinstance(co, bool)
                 else None, camera_frames=cam_frames, camera_centres=centres)


def _vectors(items: list[tuple[int, Any]], name: str, where: str, key: str
             ) -> NDArray[np.float64]:
    """(N, 2) of the per-frame 2-vector ``name`` (``pos_vehicle``, ``vel_vehicle``); NaN if absent."""
    out = np.full((len(items), 2), np.nan)
    for i, (_, v) in enumerate(items):
        p = v.get(name)
        if isinstance(p, list) and len(p) >= 2:
            out[i] = [_num(p[0], where, f"{key}.{name}", optional=False),
                      _num(p[1], where, f"{key}.{name}", optional=False)]
    return out


def _camera_centres(poses: Any, where: str
                    ) -> tuple[NDArray[np.int64] | None, NDArray[np.float64] | None]:
    """Frames (F,) and camera centres (F, 3) m of ``camera_poses`` (4x4 world-from-camera)."""
    if not isinstance(poses, dict) or not poses:
        return None, None
    rows = []
    for f, m in poses.items():
        try:
            T = np.asarray(m, dtype=np.float64)
            frame = int(f)
        except (TypeError, ValueError):
            raise UsageError(f"{where}: camera_poses.{f} must be a 4x4 matrix") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise UsageError(f"{where}: camera_poses.{f} must be a finite 4x4 matrix")
        rows.append((frame, T[:3, 3]))
    rows.sort(key=lambda r: r[0])
    return (np.array([r[0] for r in rows], dtype=np.int64),
            np.array([r[1] for r in rows], dtype=np.float64))
