"""Recording-backed sources that serve the drivers' interfaces, paced in real time.

``--realtime`` replay and the demo play a drive recording *through the drivers*:
frames through the camera interface (:class:`RecordingSource`, registered as the
camera source ``"recording"``), CAN frames onto a python-can bus where the real
vehicle CAN reader receives them (:class:`CanPlayer`), PTU positions into the PTU
ring as the PTU driver would deliver them (:class:`PtuPlayer`).

All three share one :class:`PlaybackClock`: recording time ``t_rec`` is played at
monotonic time ``t0 + (t_rec - t_rec0)``, so frames and CAN stay in step as they
were recorded. Frames are stamped on the monotonic clock like a live camera's.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import can

from appliance.recording import PtuTrack, Recording
from drivers.camera import CameraFrame, CameraStats, FrameSource, register_source
from drivers.link import LinkState
from drivers.ptu import PtuDriver, PtuSample

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PlaybackClock:
    """Maps recording time to the monotonic clock: ``mono = t0_mono + (t_rec - t0_rec) / rate``.

    ``rate`` 1 plays in real time; below 1 slower (an emulated test machine).
    """

    t0_rec: float
    t0_mono: float
    rate: float = 1.0

    def mono(self, t_rec: float) -> float:
        return self.t0_mono + (t_rec - self.t0_rec) / self.rate

    def recording(self, t_mono: float) -> float:
        """The recording time that monotonic time ``t_mono`` plays."""
        return self.t0_rec + (t_mono - self.t0_mono) * self.rate


def wait_until(stop: threading.Event, mono_t: float) -> bool:
    """Sleep until monotonic time ``mono_t``; False if ``stop`` was set meanwhile."""
    delay = mono_t - time.monotonic()
    return not stop.wait(delay) if delay > 0 else not stop.is_set()


class RecordingSource(FrameSource):
    """A camera that plays a recording's frames, paced by ``clock`` (or as fast as read).

    When the recording ends the source reports ``LinkState.LOST`` (a camera that
    stopped delivering) and sets :attr:`finished`; no frame for ``stale_s`` s reports
    ``STALE``, as the V4L2 camera does. :meth:`interrupt` injects a camera outage.
    """

    def __init__(
        self,
        recording: Recording,
        clock: PlaybackClock | None = None,
        capacity: int = 4,
        stale_s: float = 0.5,
    ) -> None:
        self.recording = recording
        self.clock = clock
        self.stale_s = stale_s
        self.finished = threading.Event()
        self._outage: tuple[float, float] | None = None
        self._last_mono: float | None = None
        self._capacity = capacity
        self._frames: list[CameraFrame] = []
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._state = LinkState.STARTING
        self._stats = CameraStats()
        self.error: Exception | None = None

    def open(self) -> None:
        self._thread = threading.Thread(target=self._run, name="camera-recording", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        captured = overwritten = 0
        try:
            for f in self.recording.frames():
                if self.clock is not None and not wait_until(self._stop, self.clock.mono(f.t)):
                    break
                t = self.clock.mono(f.t) if self.clock is not None else f.t
                out = self._outage
                if out is not None and out[0] <= time.monotonic() < out[1]:
                    continue  # the camera is "unplugged": this frame never arrives
                with self._cond:
                    self._last_mono = time.monotonic()
                    if len(self._frames) >= self._capacity:
                        self._frames.pop(0)
                        overwritten += 1
                    self._frames.append(CameraFrame(f.index, t, f.image, "recording"))
                    captured += 1
                    self._state = LinkState.OK
                    self._stats = CameraStats(
                        frames=captured,
                        delivered=self._stats.delivered,
                        overwritten=overwritten,
                        opens=1,
                    )
                    self._cond.notify_all()
                if self._stop.is_set():
                    break
        except Exception as exc:  # a corrupt recording: reported by the runtime, not raised here
            self.error = exc
            log.error("recording source %s: %s", self.recording.path, exc)
        with self._cond:
            self._state = LinkState.LOST
            self.finished.set()
            self._cond.notify_all()

    def interrupt(self, duration_s: float = math.inf) -> None:
        """Fault injection: deliver no frames for the next ``duration_s`` seconds (until
        :meth:`resume` by default)."""
        now = time.monotonic()
        self._outage = (now, now + duration_s)

    def resume(self) -> None:
        """End an outage of :meth:`interrupt` now."""
        self._outage = None

    def read(self, timeout: float) -> CameraFrame | None:
        with self._cond:
            if not self._cond.wait_for(
                lambda: bool(self._frames) or self.finished.is_set(), timeout
            ):
                return None
            if not self._frames:
                return None
            s = self._stats
            self._stats = CameraStats(
                frames=s.frames, delivered=s.delivered + 1, overwritten=s.overwritten, opens=1
            )
            return self._frames.pop(0)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self._state = LinkState.STOPPED

    @property
    def stats(self) -> CameraStats:
        return self._stats

    @property
    def state(self) -> LinkState:
        last = self._last_mono
        if (
            self._state is LinkState.OK
            and last is not None
            and time.monotonic() - last > self.stale_s
        ):
            return LinkState.STALE
        return self._state


register_source("recording", RecordingSource)


class _Player:
    """A paced playback thread with start/stop and a ``finished`` event."""

    name = "player"

    def __init__(self) -> None:
        self.finished = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: Exception | None = None

    def start(self) -> _Player:
        self._thread = threading.Thread(target=self._guarded, name=self.name, daemon=True)
        self._thread.start()
        return self

    def _guarded(self) -> None:
        try:
            self._run()
        except Exception as exc:
            self.error = exc
            log.error("%s: %s", self.name, exc)
        finally:
            self.finished.set()

    def _run(self) -> None:
        raise NotImplementedError

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)


class CanPlayer(_Player):
    """Sends a recording's CAN frames on ``bus`` at their recorded pace (the vehicle, replayed)."""

    name = "can-player"

    def __init__(
        self, messages: Iterator[can.Message], bus: can.BusABC, clock: PlaybackClock
    ) -> None:
        super().__init__()
        self._messages = messages
        self._bus = bus
        self._clock = clock
        self.sent = 0
        self.send_errors = 0
        self._mute: tuple[float, float] | None = None

    def mute(self, duration_s: float = math.inf) -> None:
        """Fault injection: the vehicle bus goes silent for the next ``duration_s`` seconds
        (until :meth:`unmute` by default)."""
        now = time.monotonic()
        self._mute = (now, now + duration_s)

    def unmute(self) -> None:
        """End a silence of :meth:`mute` now."""
        self._mute = None

    def _run(self) -> None:
        for msg in self._messages:
            if not wait_until(self._stop, self._clock.mono(msg.timestamp)):
                return
            mute = self._mute
            if mute is not None and mute[0] <= time.monotonic() < mute[1]:
                continue
            out = can.Message(
                arbitration_id=msg.arbitration_id,
                is_extended_id=msg.is_extended_id,
                is_remote_frame=msg.is_remote_frame,
                is_error_frame=msg.is_error_frame,
                is_fd=msg.is_fd,
                data=msg.data,
                dlc=msg.dlc,
            )
            try:
                self._bus.send(out, timeout=0.05)
                self.sent += 1
            except can.CanError:
                self.send_errors += 1


class PtuPlayer(_Player):
    """Hands a recording's PTU positions to ``sink`` at their recorded pace, as the driver would."""

    name = "ptu-player"

    def __init__(
        self, track: PtuTrack, sink: Callable[[PtuSample], None], clock: PlaybackClock
    ) -> None:
        super().__init__()
        self._track = track
        self._sink = sink
        self._clock = clock

    def _run(self) -> None:
        for t, pan, tilt in zip(self._track.t, self._track.pan, self._track.tilt):
            mono = self._clock.mono(float(t))
            if not wait_until(self._stop, mono):
                return
            self._sink(PtuSample(mono, float(pan), float(tilt)))


class PtuCommander(_Player):
    """Turns a real pan-tilt unit, through its driver, the way a recording's PTU turned.

    Each change of the recorded position becomes an absolute move, sent ``lead_s`` before
    its recorded time (about one poll period, so that the unit, moving with its own speed
    and acceleration limits, is there when the frame rendered with that pan is shown).
    The demo uses it so that the PTU simulator reports the pans its frames were made with.
    """

    name = "ptu-commander"

    def __init__(
        self,
        track: PtuTrack,
        driver: PtuDriver,
        clock: PlaybackClock,
        lead_s: float = 0.05,
        min_step_rad: float = 1e-4,
    ) -> None:
        super().__init__()
        self._track = track
        self._driver = driver
        self._clock = clock
        self._lead = lead_s
        self._min_step = min_step_rad

    def _run(self) -> None:
        last = (float(self._track.pan[0]), float(self._track.tilt[0]))
        for t, pan, tilt in zip(self._track.t, self._track.pan, self._track.tilt):
            target = (float(pan), float(tilt))
            if max(abs(target[0] - last[0]), abs(target[1] - last[1])) < self._min_step:
                continue
            if not wait_until(self._stop, self._clock.mono(float(t)) - self._lead):
                return
            self._driver.move_to(*target)
            last = target
