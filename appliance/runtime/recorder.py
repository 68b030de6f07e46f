"""``run --record DIR``: everything the drivers delivered, written as drive recordings.

Frames (losslessly, FFV1), raw CAN frames (``can.log``), PTU positions
(``ptu.csv``) and ``meta.toml`` from the configuration, on the monotonic clock
(the live recording clock). A new recording directory is started after
``runtime.record_rotate_s`` seconds or ``runtime.record_rotate_mb`` MB of video,
so a long drive becomes several replayable pieces. The drivers' threads only
queue items (never blocking); a writer thread does the encoding and the disk I/O.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import can

from appliance.config import Config
from appliance.recording import RecordingWriter, meta_from_config
from drivers.camera import CameraFrame
from drivers.ptu import PtuSample

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecorderStats:
    recordings: int
    frames: int
    can_frames: int
    ptu_samples: int
    dropped: int
    errors: int


class LiveRecorder:
    """Queues what the drivers deliver and writes it as rotating drive recordings under ``base``."""

    def __init__(self, base: str | Path, cfg: Config, queue_size: int = 2048) -> None:
        self.base = Path(base)
        self.base.mkdir(parents=True, exist_ok=True)
        self.cfg = cfg
        self.rotate_s = cfg.runtime.record_rotate_s
        self.rotate_bytes = cfg.runtime.record_rotate_mb * 1e6
        self._queue: queue.Queue[CameraFrame | can.Message | PtuSample | None] = queue.Queue(
            queue_size
        )
        self._writer: RecordingWriter | None = None
        self._segment_t0: float | None = None
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        self.paths: list[Path] = []
        # monotonic -> recording clock; live they are the same. A slowed playback
        # (runtime.replay_rate) sets its clock here, so the recording keeps the drive's time.
        self.to_recording: Callable[[float], float] = lambda t: t
        self._n = {"frames": 0, "can": 0, "ptu": 0, "dropped": 0, "errors": 0}

    def start(self) -> LiveRecorder:
        self._thread.start()
        return self

    # called on driver threads: never block
    def _put(self, item: CameraFrame | can.Message | PtuSample) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self._n["dropped"] += 1

    def add_frame(self, frame: CameraFrame) -> None:
        self._put(frame)

    def add_can(self, msg: can.Message) -> None:
        self._put(msg)

    def add_ptu(self, sample: PtuSample) -> None:
        self._put(sample)

    def stop(self, timeout: float = 2.0) -> None:
        """Write what is queued, close the current recording."""
        self._queue.put(None)
        self._thread.join(timeout)

    @property
    def stats(self) -> RecorderStats:
        n = self._n
        return RecorderStats(
            len(self.paths), n["frames"], n["can"], n["ptu"], n["dropped"], n["errors"]
        )

    # writer thread
    def _run(self) -> None:
        pending: list[
            can.Message | PtuSample
        ] = []  # sensor data before the first frame of a segment
        while True:
            item = self._queue.get()
            if item is None:
                break
            try:
                if isinstance(item, CameraFrame):
                    self._frame(item, pending)
                    pending = []
                elif self._writer is None:
                    pending.append(item)
                    del pending[:-2000]
                else:
                    self._sensor(item)
            except (
                Exception
            ) as exc:  # disk full, permissions: count, log, keep the appliance running
                self._n["errors"] += 1
                log.error("recorder: %s: %s", type(exc).__name__, exc)
        self._close()

    def _frame(self, frame: CameraFrame, pending: list[can.Message | PtuSample]) -> None:
        w = self._writer
        if (
            w is not None
            and self._segment_t0 is not None
            and (frame.t - self._segment_t0 >= self.rotate_s or w.video_bytes >= self.rotate_bytes)
        ):
            self._close()
            w = None
        if w is None:
            name = time.strftime("drive-%Y%m%d-%H%M%S") + f"-{len(self.paths):03d}"
            w = self._writer = RecordingWriter(
                self.base / name, meta_from_config(self.cfg), fps=self.cfg.camera.fps
            )
            self._segment_t0 = frame.t
            self.paths.append(w.path)
            log.info("recording to %s", w.path)
            for item in pending:
                self._sensor(item)
        t = self.to_recording(frame.t)
        if w.last_t is not None and t <= w.last_t:
            self._n["errors"] += 1  # a camera clock step backwards: keep the recording valid
            return
        w.write_frame(frame.image, t)
        self._n["frames"] += 1

    def _sensor(self, item: can.Message | PtuSample) -> None:
        assert self._writer is not None
        if isinstance(item, PtuSample):
            self._writer.write_ptu(self.to_recording(item.t), item.pan_rad, item.tilt_rad)
            self._n["ptu"] += 1
        else:
            item.timestamp = self.to_recording(item.timestamp)
            self._writer.write_can(item)
            self._n["can"] += 1

    def _close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None
            self._segment_t0 = None
