"""Threads and time: drivers -> ring buffers -> processing -> outputs, started and stopped in order.

Threads: camera capture (this module), vehicle CAN (the reader's python-can
Notifier), PTU polling (the PTU driver), processing (this module: newest frame,
sensors interpolated to its capture time, ``pipeline.step``, HMI publish) and
output (this module: the logs). No driver thread ever blocks on the pipeline: each
hands its data to a ring buffer that overwrites its oldest entry when full.

Times: the pipeline and the outputs run on the recording clock, which live *is*
the monotonic clock (offset 0); a real-time replay adds the offset of its
:class:`~appliance.runtime.sources.PlaybackClock`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from appliance.config import Config
from appliance.errors import RuntimeFailure
from appliance.messages import Frame, StepOutput, WarningEvent
from appliance.pipeline import PipelineState, camera_from_config, init_state, step
from appliance.runtime.health import Faults, Health, HealthStatus
from appliance.runtime.outputs import RunOutputs, timing_stats
from appliance.runtime.sd_notify import SdNotifier
from appliance.runtime.sensor_sync import SensorSync
from appliance.runtime.waiting import StillWaiting
from appliance.runtime.wiring import hmi_status, hmi_warning
from drivers.camera import CameraFrame, FrameSource
from drivers.handoff import Handoff
from drivers.hmi_can import HmiCanStats, HmiCanWriter
from drivers.link import LinkState
from drivers.ptu import PtuSample
from drivers.vehicle_signals import SignalKind, VehicleSignal

log = logging.getLogger(__name__)

# ring buffer capacities: frames (the newest are kept), vehicle CAN samples, PTU samples
FRAME_RING = 4
CAN_RING = 1024
PTU_RING = 256


class Stoppable(Protocol):
    def stop(self) -> None: ...


class Recorder(Protocol):
    def add_frame(self, frame: CameraFrame) -> None: ...

    def add_ptu(self, sample: PtuSample) -> None: ...


@dataclass
class LiveInputs:
    """What feeds a live run. The supervisor wires the rings into the drivers' sinks itself.

    ``camera`` is opened and closed by the supervisor; ``vehicle``/``ptu``/``hmi`` are
    started by the caller (so their sinks can point at :attr:`Supervisor.can_ring` /
    :attr:`Supervisor.ptu_ring`) and stopped by the supervisor in order. ``players``
    are extra threads to stop (recording players, simulators).
    """

    camera: FrameSource
    vehicle: Any | None = None
    ptu: Any | None = None
    hmi: HmiCanWriter | None = None
    players: list[Stoppable] = field(default_factory=list)
    to_recording: Callable[[float], float] | None = None  # monotonic -> recording time; None: same
    ptu_enabled: bool = True
    finished: threading.Event | None = None  # set when a recording source ran out


@dataclass
class RunStats:
    frames_read: int = 0
    frames_processed: int = 0
    stage_ms: dict[str, list[float]] = field(
        default_factory=lambda: {"vision": [], "decision": [], "total": [], "end_to_end": []}
    )
    status_changes: list[str] = field(default_factory=list)
    warnings: list[WarningEvent] = field(default_factory=list)
    first_frame_t: float | None = None
    last_frame_t: float | None = None
    hmi: HmiCanStats | None = None  # what the HMI writer sent, once it has stopped


class Supervisor:
    """Owns the ring buffers and the capture, processing and output threads of one run."""

    def __init__(
        self,
        cfg: Config,
        outputs: RunOutputs,
        notifier: SdNotifier | None = None,
        on_event: Callable[[str], None] | None = None,
        recorder: Recorder | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.cfg = cfg
        self.camera_model = camera_from_config(cfg)
        self.outputs = outputs
        self.notifier = notifier or SdNotifier("")
        self.on_event = on_event or (lambda line: log.info("%s", line))
        self.recorder = recorder
        self.clock = clock
        self.frame_ring: Handoff[CameraFrame] = Handoff(FRAME_RING)
        self.can_ring: Handoff[VehicleSignal] = Handoff(CAN_RING)
        self.ptu_ring: Handoff[PtuSample] = Handoff(PTU_RING)
        self._out_ring: Handoff[StepOutput | WarningEvent] = Handoff(4096)
        self.health = Health()
        self.stats = RunStats()
        self.stop_event = threading.Event()
        self._processing_done = threading.Event()
        self._latency: deque[tuple[float, float]] = deque()  # (mono time, ms) of the last second
        self._drops: deque[tuple[float, int]] = deque()
        self._warning_level = 0
        self._last_frame = -1
        self._waiting = StillWaiting()
        self.failure: BaseException | None = None

    # ------------------------------------------------------------------ public

    def add_ptu(self, sample: PtuSample) -> None:
        """The PTU driver's (or player's) sink: into :attr:`ptu_ring`, and recorded."""
        self.ptu_ring.put(sample)
        if self.recorder is not None:
            self.recorder.add_ptu(sample)

    def run(self, inputs: LiveInputs, max_seconds: float | None = None) -> RunStats:
        """Run until :attr:`stop_event` is set (a signal), a recording source ends or
        ``max_seconds`` pass."""
        threads = [
            threading.Thread(
                target=self._guard, args=(self._capture_loop, inputs), name="capture", daemon=True
            ),
            threading.Thread(
                target=self._guard,
                args=(self._processing_loop, inputs),
                name="processing",
                daemon=True,
            ),
            threading.Thread(
                target=self._guard, args=(self._output_loop,), name="output", daemon=True
            ),
        ]
        inputs.camera.open()
        for th in threads:
            th.start()
        deadline = None if max_seconds is None else self.clock() + max_seconds
        while not self.stop_event.is_set():
            if self._processing_done.wait(0.1):
                break
            if deadline is not None and self.clock() >= deadline:
                break
        self.shutdown(inputs, threads)
        if self.failure is not None:
            raise RuntimeFailure(f"{type(self.failure).__name__}: {self.failure}") from self.failure
        return self.stats

    def _guard(self, target: Callable[..., None], *args: Any) -> None:
        """A thread's body: an unexpected error stops the run (exit 1, systemd restarts it)."""
        try:
            target(*args)
        except Exception as exc:
            log.exception("%s thread failed", threading.current_thread().name)
            self.failure = exc
            self.stop_event.set()
            self._processing_done.set()

    def shutdown(self, inputs: LiveInputs, threads: list[threading.Thread]) -> None:
        """Stop in reverse order of the data flow; every join is bounded (2 s in all)."""
        self.notifier.stopping()
        self.stop_event.set()
        self.frame_ring.close()
        end = time.monotonic() + 1.5
        for th in threads[:2]:
            th.join(max(0.0, end - time.monotonic()))
        self._out_ring.close()
        threads[2].join(max(0.1, end - time.monotonic()))
        log.debug("threads joined")
        inputs.camera.close()
        log.debug("camera closed")
        for part in (inputs.vehicle, inputs.ptu, inputs.hmi):
            if part is not None:
                part.stop(timeout=0.5)
                log.debug("stopped %s", type(part).__name__)
        if inputs.hmi is not None:
            self.stats.hmi = inputs.hmi.stats
        for player in inputs.players:  # after the drivers, so a simulator outlives its driver
            player.stop()
        self.outputs.flush()

    # ------------------------------------------------------------------ capture thread

    def _capture_loop(self, inputs: LiveInputs) -> None:
        while not self.stop_event.is_set():
            frame = inputs.camera.read(timeout=0.1)
            if frame is None:
                if inputs.finished is not None and inputs.finished.is_set():
                    break
                continue
            self.stats.frames_read += 1
            self.frame_ring.put(frame)
            if self.recorder is not None:
                self.recorder.add_frame(frame)
        self.frame_ring.close()

    # ------------------------------------------------------------------ processing thread

    def _processing_loop(self, inputs: LiveInputs) -> None:
        cfg = self.cfg
        sync = SensorSync(
            cfg.vehicle_can.stale_s,
            max(cfg.vehicle_can.stale_s, 2.0 / cfg.ptu.poll_hz),
            ptu_present=inputs.ptu_enabled,
        )
        state: PipelineState | None = None
        rt = inputs.to_recording or (lambda t: t)
        last_status = 0.0
        camera_lost = False
        try:
            while not self.stop_event.is_set():
                cf = self.frame_ring.take_newest(timeout=0.1)
                now = self.clock()
                self.notifier.watchdog()
                for v in self.can_ring.drain():
                    (sync.add_speed if v.kind is SignalKind.SPEED else sync.add_yaw_rate)(
                        rt(v.t), v.value
                    )
                for p in self.ptu_ring.drain():
                    sync.add_ptu(rt(p.t), p.pan_rad, p.tilt_rad)
                cam_state = inputs.camera.state
                lost = cam_state in (LinkState.LOST, LinkState.STALE) and cf is None
                ended = inputs.finished is not None and inputs.finished.is_set()
                if lost and not camera_lost and not ended:
                    self._clear_warnings(inputs, rt(now), state)
                    state = None  # the scene has moved on: start afresh when frames return
                camera_lost = lost
                if cf is None:
                    if self.frame_ring.closed and len(self.frame_ring) == 0:
                        break
                    self._update_health(inputs, now, None, camera_lost)
                    continue
                if state is None:
                    state = init_state(cfg, self.camera_model)
                frame = Frame(cf.index, rt(cf.t), cf.image)
                self._last_frame = cf.index
                sensors = sync.sample(frame.t)
                state, out, decision = step(state, frame, sensors, cfg, self.camera_model)
                self._warning_level = decision.warning_level
                done = self.clock()
                latency_ms = (done - cf.t) * 1e3
                if inputs.hmi is not None:
                    inputs.hmi.publish(
                        warning=hmi_warning(decision.warning_level, decision.warning_track)
                    )
                self._record_timing(out, latency_ms, done)
                self._out_ring.put(out)
                status = self._update_health(inputs, done, sensors, False)
                if self.stats.frames_processed == 1:
                    self.notifier.ready(f"first frame processed; {status.describe()}")
                if done - last_status >= 1.0:
                    self.notifier.status(status.describe())
                    last_status = done
        finally:
            self._processing_done.set()

    def _record_timing(self, out: StepOutput, latency_ms: float, now: float) -> None:
        s = self.stats
        s.frames_processed += 1
        if s.first_frame_t is None:
            s.first_frame_t = out.t
        s.last_frame_t = out.t
        for k, v in out.stage_ms.items():
            s.stage_ms.setdefault(k, []).append(v)
        s.stage_ms["end_to_end"].append(latency_ms)
        self._latency.append((now, latency_ms))
        while self._latency and self._latency[0][0] < now - 1.0:
            self._latency.popleft()

    def _update_health(
        self, inputs: LiveInputs, now: float, sensors: Any, camera_lost: bool
    ) -> HealthStatus:
        dropped = self.frame_ring.stats().dropped + inputs.camera.stats.overwritten
        self._drops.append((now, dropped))
        while self._drops and self._drops[0][0] < now - 1.0:
            self._drops.popleft()
        overrun = dropped > self._drops[0][1]
        can_stale = sensors is not None and not sensors.can_valid
        if inputs.vehicle is not None:
            can_stale = can_stale or inputs.vehicle.state_at(time.monotonic()) is not LinkState.OK
        ptu_bad = False
        if inputs.ptu is not None and inputs.ptu_enabled:
            ptu_bad = inputs.ptu.state is not LinkState.OK
        faults = Faults(
            camera=camera_lost, vehicle_can_stale=can_stale, ptu=ptu_bad, overrun=overrun
        )
        lat = [ms for _, ms in self._latency]
        rate = float(len(lat))
        change = self.health.update(
            self.stats.frames_processed > 0, faults, rate, float(np.median(lat)) if lat else 0.0
        )
        if change is not None:
            self.stats.status_changes.append(change)
            self.on_event(change)
        if inputs.hmi is not None:
            inputs.hmi.publish(status=hmi_status(self.health.status))
        self._report_missing(inputs, now)
        return self.health.status

    def _report_missing(self, inputs: LiveInputs, now: float) -> None:
        """Every 10 s, one line per device still lost or silent (``runtime.waiting``)."""
        if inputs.finished is not None and inputs.finished.is_set():
            return
        parts: list[tuple[str, Any, LinkState]] = [
            ("camera", inputs.camera, inputs.camera.state)
        ]
        if inputs.vehicle is not None:
            parts.append(("vehicle CAN", inputs.vehicle, inputs.vehicle.state_at(time.monotonic())))
        if inputs.ptu is not None and inputs.ptu_enabled:
            parts.append(("PTU", inputs.ptu, inputs.ptu.state))
        if inputs.hmi is not None:
            parts.append(("HMI CAN", inputs.hmi, inputs.hmi.state))
        for name, part, state in parts:
            missing = state in (LinkState.LOST, LinkState.STALE)
            why = (part.stats.last_error or f"{state.value}: nothing received") if missing else ""
            line = self._waiting.update(now, name, missing, why)
            if line is not None:
                self.on_event(line)

    def _clear_warnings(self, inputs: LiveInputs, t: float, state: PipelineState | None) -> None:
        """Camera lost: an active warning is cleared (a blind appliance must not keep warning)."""
        if self._warning_level > 0:
            self._out_ring.put(
                WarningEvent(
                    t=t,
                    frame=self._last_frame,
                    level=0,
                    track=None,
                    bbox=None,
                    ttc_s=None,
                    distance_m=None,
                    bearing_rad=None,
                )
            )
            if inputs.hmi is not None:
                inputs.hmi.publish(warning=hmi_warning(0, None))
            self._warning_level = 0

    # ------------------------------------------------------------------ output thread

    def _output_loop(self) -> None:
        while True:
            out = self._out_ring.get(timeout=0.2)
            if out is None:
                if self._out_ring.closed:
                    break
                continue
            if isinstance(out, WarningEvent):
                events: tuple[WarningEvent, ...] = (out,)
                self.outputs.write_warnings(events)
            else:
                events = out.warnings
                self.outputs.write_step(out)
            for w in events:
                self.stats.warnings.append(w)
                self.on_event(describe_warning(w))


def describe_warning(w: WarningEvent) -> str:
    name = {0: "cleared", 1: "CAUTION", 2: "WARNING"}.get(w.level, str(w.level))
    ttc = "" if w.ttc_s is None else f" ttc {w.ttc_s:.2f} s"
    dist = "" if w.distance_m is None else f" distance {w.distance_m:.1f} m"
    track = "" if w.track is None else f" track {w.track}"
    return f"t={w.t:.2f} frame {w.frame}: {name}{track}{ttc}{dist}"


def run_summary(
    stats: RunStats, cfg: Config, extra: dict[str, Any] | None = None
) -> dict[str, Any]:
    """``summary.json`` of a live run: ``can_frames_sent`` is what the HMI writer put on the
    bus (and logged in ``can_out.log``); ``hmi_can`` also counts the frames it could not send."""
    hmi = stats.hmi or HmiCanStats()
    return {
        "frames_read": stats.frames_read,
        "frames_processed": stats.frames_processed,
        "frames_dropped": stats.frames_read - stats.frames_processed,
        "processing_ms": {k: timing_stats(v) for k, v in stats.stage_ms.items()},
        "status_changes": stats.status_changes,
        "config_digest": cfg.digest(),
        "can_frames_sent": hmi.sent,
        "hmi_can": {
            "produced": hmi.produced,
            "sent": hmi.sent,
            "dropped_queue_full": hmi.dropped_queue_full,
            "expired": hmi.expired,
            "send_errors": hmi.send_errors,
            "bus_lost": hmi.bus_lost,
        },
        **(extra or {}),
    }
