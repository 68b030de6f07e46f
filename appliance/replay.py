"""``collision-warning replay RECORDING --out DIR``: the pipeline on a drive recording.

As fast as it can by default: frames, CAN frames and PTU samples are merged in
time order and fed to the same ``pipeline.step`` as live; the outputs are written
by ``runtime.outputs``. Deterministic: two replays of one recording with one
configuration give identical warnings, tracks, ego-motion and CAN output.
``--realtime`` instead plays the recording through the drivers' sources, ring
buffers and threads, exactly as live (``runtime.supervisor``).

A gap between frames longer than ``camera.stale_s`` is a camera outage, as live: the status
says so, a warning then active is cleared, and the pipeline starts afresh.

``--config FILE`` is checked as ``run`` checks it (its DBCs and signal names too), even
where the recording's ``[can]`` table takes the place of its ``[vehicle_can]`` decoding;
one line says when it does. ``--out`` must be new or empty, or hold an earlier run's files
with ``--force`` (``runtime.run_dir``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can

from appliance.config import Config, load_config, read_toml
from appliance.errors import UsageError
from appliance.messages import Frame, StepOutput, WarningEvent
from appliance.pipeline import camera_from_config, init_state, step
from appliance.recording import Recording, apply_meta
from appliance.runtime.health import Faults, Health
from appliance.runtime.outputs import RunOutputs, timing_stats
from appliance.runtime.run_dir import prepare_run_dir
from appliance.runtime.sensor_sync import SensorSync
from appliance.runtime.wiring import (
    check_config,
    hmi_codec,
    hmi_status,
    hmi_warning,
    vehicle_decoder,
)
from drivers.hmi_can import HmiScheduler
from drivers.vehicle_signals import FrameDecodeError, SignalKind

# CAN and PTU samples up to this long after a frame's capture time are used for it
# (live, the processing thread sees the samples that arrived while the frame was in
# flight; this models that delay deterministically).
SENSOR_LOOKAHEAD_S = 0.02


@dataclass
class ReplayResult:
    frames_read: int = 0
    frames_processed: int = 0
    can_frames: int = 0
    status_changes: list[str] = field(default_factory=list)
    can_errors: dict[str, int] = field(default_factory=dict)
    stage_ms: dict[str, list[float]] = field(default_factory=dict)
    wall_s: float = 0.0


def open_recording(path: str | Path, cfg: Config) -> tuple[Recording, Config]:
    """Open and validate a recording; its meta overrides camera, mount and CAN decoding."""
    rec = Recording(path, defaults=cfg)
    rec.validate()
    return rec, apply_meta(cfg, rec.meta)


class _Peek:
    """An iterator with one item of look-ahead."""

    def __init__(self, it: Iterator[Any]) -> None:
        self._it = it
        self.head: Any = next(it, None)

    def pop(self) -> Any:
        item, self.head = self.head, next(self._it, None)
        return item


def replay(
    rec: Recording,
    cfg: Config,
    out_dir: str | Path,
    on_step: Callable[[Frame, StepOutput, Any], None] | None = None,
    progress: bool = False,
) -> ReplayResult:
    """Run the pipeline over ``rec`` as fast as possible, writing the outputs to ``out_dir``."""
    camera = camera_from_config(cfg)
    decoder = vehicle_decoder(cfg)
    ptu = rec.ptu()
    sync = SensorSync(
        cfg.vehicle_can.stale_s,
        max(cfg.vehicle_can.stale_s, 2.0 / cfg.ptu.poll_hz),
        ptu_present=ptu is not None,
    )
    state = init_state(cfg, camera)
    hmi = HmiScheduler(hmi_codec(cfg), cfg.hmi_can.period_s)
    health = Health()
    fps = _frame_rate(rec)
    result = ReplayResult(stage_ms={"vision": [], "decision": [], "total": [], "end_to_end": []})
    can_it = _Peek(rec.can_messages())
    ptu_i = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(
            total=rec.n_frames, unit="frame", file=sys.stderr, desc=rec.path.name, leave=False
        )
    t_start = time.perf_counter()
    last: tuple[float, int, int] | None = None   # the previous frame's time, index, warning level
    with RunOutputs(out_dir) as outputs:
        for frame in rec.frames():
            result.frames_read += 1
            if last is not None and frame.t - last[0] > cfg.camera.stale_s:
                # no frame for longer than the camera's stale time: the camera was lost, as live
                # (runtime.supervisor): its warning is cleared and the pipeline starts afresh
                lost_t = last[0] + cfg.camera.stale_s
                change = health.update(True, Faults(camera=True), fps, 0.0)
                if change is not None:
                    result.status_changes.append(f"{lost_t:.3f} {change}")
                if last[2] > 0:
                    outputs.write_warnings([WarningEvent(t=lost_t, frame=last[1], level=0,
                                                         track=None, bbox=None, ttc_s=None,
                                                         distance_m=None, bearing_rad=None)])
                outputs.write_can(hmi.update(lost_t, hmi_warning(0, None), hmi_status(health.status)))
                state = init_state(cfg, camera)
            horizon = frame.t + SENSOR_LOOKAHEAD_S
            while can_it.head is not None and can_it.head.timestamp <= horizon:
                _feed_can(can_it.pop(), decoder, sync, result)
            if ptu is not None:
                while ptu_i < len(ptu.t) and ptu.t[ptu_i] <= horizon:
                    sync.add_ptu(float(ptu.t[ptu_i]), float(ptu.pan[ptu_i]), float(ptu.tilt[ptu_i]))
                    ptu_i += 1
            c0 = time.perf_counter()
            sensors = sync.sample(frame.t)
            state, out, decision = step(state, frame, sensors, cfg, camera)
            outputs.write_step(out)
            last = (frame.t, frame.index, decision.warning_level)
            # ApplianceStatus as live, except latency: an as-fast-as-possible replay has no
            # capture-to-output latency, so it reports 0 (summary.json has the timings)
            faults = Faults(vehicle_can_stale=not sensors.can_valid, ptu=not sensors.ptu_valid)
            change = health.update(True, faults, fps, 0.0)
            if change is not None:
                result.status_changes.append(f"{frame.t:.3f} {change}")
            outputs.write_can(
                hmi.update(
                    frame.t,
                    hmi_warning(decision.warning_level, decision.warning_track),
                    hmi_status(health.status),
                )
            )
            c1 = time.perf_counter()
            result.frames_processed += 1
            for k, v in out.stage_ms.items():
                result.stage_ms[k].append(v)
            result.stage_ms["end_to_end"].append((c1 - c0) * 1e3)
            if on_step is not None:
                on_step(frame, out, decision)
            if bar is not None:
                bar.update(1)
        result.wall_s = time.perf_counter() - t_start
        outputs.write_summary(summary(result, cfg))
    if bar is not None:
        bar.close()
    return result


def _frame_rate(rec: Recording) -> float:
    """Frame rate on the recording clock (1/s)."""
    t = rec.frame_times
    return float((len(t) - 1) / (t[-1] - t[0])) if len(t) > 1 and t[-1] > t[0] else 0.0


def _feed_can(msg: can.Message, decoder: Any, sync: SensorSync, result: ReplayResult) -> None:
    result.can_frames += 1
    if msg.is_error_frame:
        result.can_errors["error_frames"] = result.can_errors.get("error_frames", 0) + 1
        return
    if not decoder.wants(msg.arbitration_id, msg.is_extended_id):
        return
    try:
        values = decoder.decode(msg.arbitration_id, msg.data, msg.timestamp, msg.is_extended_id)
    except FrameDecodeError as exc:
        result.can_errors[exc.reason] = result.can_errors.get(exc.reason, 0) + 1
        return
    for v in values:
        if not math.isfinite(v.value):
            continue
        if v.kind is SignalKind.SPEED:
            sync.add_speed(v.t, v.value)
        else:
            sync.add_yaw_rate(v.t, v.value)


def summary(result: ReplayResult, cfg: Config) -> dict[str, Any]:
    return {
        "frames_read": result.frames_read,
        "frames_processed": result.frames_processed,
        "frames_dropped": result.frames_read - result.frames_processed,
        "processing_ms": {k: timing_stats(v) for k, v in result.stage_ms.items()},
        "replay_frames_per_s": round(result.frames_processed / result.wall_s, 2)
        if result.wall_s
        else None,
        "can_frames_read": result.can_frames,
        "can_errors": dict(sorted(result.can_errors.items())),
        "status_changes": result.status_changes,
        "config_digest": cfg.digest(),
    }


# the [vehicle_can] keys a recording's [can] table replaces
DECODING_KEYS = ("dbc", "speed", "speed_unit", "yaw_rate", "yaw_rate_unit", "yaw_rate_sign")


def decoding_override(config_path: str, own: Config, used: Config) -> str | None:
    """One line when the recording's ``[can]`` replaced decoding keys that ``config_path`` set."""
    named = read_toml(config_path).get("vehicle_can", {})
    replaced = [
        k for k in DECODING_KEYS
        if k in named and getattr(own.vehicle_can, k) != getattr(used.vehicle_can, k)
    ]
    if not replaced:
        return None
    keys = ", ".join(f"vehicle_can.{k}" for k in replaced)
    return (
        f"note: {config_path}: {keys} not used: the recording's meta.toml [can] table "
        "decodes its CAN (a recording carries its own vehicle's decoding)"
    )


def main(args: argparse.Namespace) -> int:
    if args.realtime and args.video:
        raise UsageError(
            "--video is only available without --realtime (replay the same recording "
            "as fast as possible to draw it)"
        )
    own: Config = getattr(args, "cfg", None) or load_config(args.config)
    if args.config:
        check_config(own)
    rec, cfg = open_recording(args.recording, own)
    if args.config:
        note = decoding_override(args.config, own, cfg)
        if note is not None:
            print(f"collision-warning replay: {note}", file=sys.stderr)
    out_dir = prepare_run_dir(args.out, args.force)
    if args.realtime:
        from appliance.runtime.realtime_replay import Buses, replay_realtime

        # the configured buses when the user gave a configuration, else private virtual ones
        buses = Buses.from_config(cfg) if args.config else Buses.private_virtual()
        replay_realtime(rec, cfg, out_dir, buses=buses)
        return 0
    video = None
    on_step = None
    if args.video:
        from appliance.runtime.annotate import AnnotatedVideo, annotate

        video = AnnotatedVideo(args.video, (cfg.camera.width, cfg.camera.height), 30.0)

        def on_step(frame: Frame, out: StepOutput, decision: Any) -> None:
            assert video is not None
            video.write(annotate(frame, out, getattr(decision, "clusters", ())))

    try:
        result = replay(rec, cfg, out_dir, on_step=on_step, progress=not args.no_progress)
    finally:
        if video is not None:
            video.close()
    print(
        f"replayed {result.frames_processed} frames of {rec.path} in {result.wall_s:.1f} s "
        f"({result.frames_processed / max(result.wall_s, 1e-9):.1f} frames/s) -> {out_dir}"
    )
    return 0
