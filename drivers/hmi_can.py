"""HMI CAN writer: when to send ``CollisionWarning``/``ApplianceStatus``, and sending them.

:class:`HmiScheduler` is the pure, time-driven core (the spec's rule, with ``period_s``
= 100 ms by default):

- ``CollisionWarning`` at once whenever the level or the track changes (a change to
  level 0 is sent once: "cleared"), and every ``period_s`` while the level is > 0,
  carrying the latest TTC, distance and bearing;
- ``ApplianceStatus`` every ``period_s`` from the first update on.

Each message has its own rolling 4-bit counter, one count per frame produced. Time
is an argument, so a replay feeds recording-clock times and gets the same frames at
the same times on every run. Periodic frames keep a fixed grid (no drift); after a
gap longer than a period the grid restarts at the current time.

:class:`HmiCanWriter` runs the core live: :meth:`~HmiCanWriter.publish` stores the
latest state and wakes a scheduler thread (never blocks); frames go to a bounded
transmit queue (full: the frame is dropped and counted) drained by a sender thread
that owns the python-can bus, reopens it with back-off when it fails, stamps each
frame with the monotonic send time and logs it to ``can_out.log`` (candump -L, via
python-can's ``CanutilsLogWriter``; a log left by an earlier writer is replaced, so the log
and ``stats.sent`` count the same frames). Frames older than two periods when their turn
comes (the bus was down) are dropped as ``expired`` rather than sent late.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from drivers.backoff import Backoff
from drivers.hmi_codec import HmiCodec, HmiStatus, HmiWarning
from drivers.link import Counters, LinkState, LinkStatus, Reporting
from drivers.vehicle_can import BusFactory, open_bus, open_error

log = logging.getLogger(__name__)

SEND_ERRORS_BEFORE_REOPEN = 3


class HmiScheduler:
    """Pure scheduling core: ``update(now, warning, status) -> frames due now``."""

    def __init__(self, codec: HmiCodec, period_s: float = 0.1) -> None:
        if not period_s > 0.0:
            raise ValueError(f"period_s must be > 0, got {period_s}")
        self.codec = codec
        self.period_s = period_s
        self._warning_key: tuple[int, int] = (0, 0)    # (level, track) last sent; 0 = cleared
        self._warning_due: float | None = None
        self._status_due: float | None = None
        self._counters = {"warning": 0, "status": 0}

    def next_due(self) -> float | None:
        """Earliest time a periodic frame is due (None before the first update)."""
        dues = [d for d in (self._warning_due, self._status_due) if d is not None]
        return min(dues) if dues else None

    def update(self, now: float, warning: HmiWarning, status: HmiStatus) -> list[can.Message]:
        out: list[can.Message] = []
        level = min(2, max(0, int(warning.level)))
        key = (level, int(warning.track_id) % 256 if level > 0 else 0)
        if key != self._warning_key:
            out.append(self._next("warning", self.codec.warning_message, warning, now))
            self._warning_key = key
            self._warning_due = now + self.period_s if level > 0 else None
        elif level > 0 and self._warning_due is not None and now >= self._warning_due:
            out.append(self._next("warning", self.codec.warning_message, warning, now))
            self._warning_due = _advance(self._warning_due, now, self.period_s)
        if self._status_due is None or now >= self._status_due:
            out.append(self._next("status", self.codec.status_message, status, now))
            self._status_due = now + self.period_s if self._status_due is None else \
                _advance(self._status_due, now, self.period_s)
        return out

    def _next(self, which: str, make: Callable[[Any, int, float], can.Message],
              payload: HmiWarning | HmiStatus, now: float) -> can.Message:
        counter = self._counters[which]
        self._counters[which] = (counter + 1) % 16
        return make(payload, counter, now)


def _advance(due: float, now: float, period: float) -> float:
    """Next slot on the grid ``due + k period``; restart at ``now`` after a long gap."""
    nxt = due + period
    return nxt if nxt > now else now + period


@dataclass(frozen=True)
class HmiCanStats:
    updates: int = 0
    produced: int = 0
    sent: int = 0
    dropped_queue_full: int = 0
    expired: int = 0
    send_errors: int = 0
    opens: int = 0
    open_failures: int = 0
    bus_lost: int = 0
    last_error: str = ""


class HmiCanWriter(Reporting[HmiCanStats]):
    """Live HMI writer; see the module docstring.

    :param log_path: where to log every sent frame (candump -L); None: no log.
    :param bus_factory: ``(interface, channel, can_filters, **bus_kwargs) -> BusABC``.
    """

    def __init__(self, codec: HmiCodec, *, interface: str = "socketcan", channel: str = "can0",
                 period_s: float = 0.1, tx_queue: int = 64, log_path: str | Path | None = None,
                 reopen_min_s: float = 0.5, reopen_max_s: float = 5.0, send_timeout_s: float = 0.05,
                 bus_kwargs: dict[str, Any] | None = None,
                 bus_factory: BusFactory = open_bus) -> None:
        self.scheduler = HmiScheduler(codec, period_s)
        self.interface = interface
        self.channel = channel
        self._queue: queue.Queue[can.Message] = queue.Queue(maxsize=tx_queue)
        self._log_path = Path(log_path) if log_path is not None else None
        self._backoff = Backoff(reopen_min_s, reopen_max_s)
        self._send_timeout = send_timeout_s
        self._bus_kwargs = dict(bus_kwargs or {})
        self._factory = bus_factory
        self._status = LinkStatus(f"HMI CAN {interface}:{channel}", log)
        self._counts = Counters()
        self._stats_type = HmiCanStats
        self._cond = threading.Condition()
        self._warning = HmiWarning()
        self._appliance = HmiStatus()
        self._changed = True    # the first status ("starting") goes out at once
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    # ---------------------------------------------------------------- public

    def start(self) -> HmiCanWriter:
        self._threads = [
            threading.Thread(target=self._schedule_loop, name="hmi-schedule", daemon=True),
            threading.Thread(target=self._send_loop, name="hmi-send", daemon=True)]
        for t in self._threads:
            t.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        for t in self._threads:
            t.join(timeout)
        self._status.set(LinkState.STOPPED)

    def __enter__(self) -> HmiCanWriter:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def publish(self, warning: HmiWarning | None = None, status: HmiStatus | None = None) -> None:
        """Set the latest warning and/or status; never blocks. A change is sent at once."""
        with self._cond:
            if warning is not None:
                self._warning = warning
            if status is not None:
                self._appliance = status
            self._changed = True
            self._cond.notify_all()

    # ---------------------------------------------------------------- threads

    def _schedule_loop(self) -> None:
        while not self._stop.is_set():
            with self._cond:
                due = self.scheduler.next_due()
                timeout = None if due is None else max(0.0, due - time.monotonic())
                if not self._changed and (timeout is None or timeout > 0.0):
                    self._cond.wait(0.5 if timeout is None else timeout)
                warning, status, self._changed = self._warning, self._appliance, False
            if self._stop.is_set():
                break
            frames = self.scheduler.update(time.monotonic(), warning, status)
            self._counts.add("updates")
            for frame in frames:
                self._counts.add("produced")
                try:
                    self._queue.put_nowait(frame)
                except queue.Full:
                    self._counts.add("dropped_queue_full", error="transmit queue full")

    def _send_loop(self) -> None:
        writer = can.CanutilsLogWriter(str(self._log_path)) if self._log_path else None
        bus: can.BusABC | None = None
        errors = 0
        try:
            while not self._stop.is_set():
                if bus is None:
                    bus = self._open()
                    if bus is None:
                        self._stop.wait(self._backoff.next_delay())
                        continue
                    errors = 0
                try:
                    frame = self._queue.get(timeout=0.1)
                except queue.Empty:
                    continue
                now = time.monotonic()
                if now - frame.timestamp > 2.0 * self.scheduler.period_s:
                    self._counts.add("expired")
                    continue
                frame.timestamp = now
                try:
                    bus.send(frame, timeout=self._send_timeout)
                except can.CanError as exc:
                    errors += 1
                    self._counts.add("send_errors", error=f"send: {exc}")
                    closed = isinstance(exc, can.CanOperationError) and "closed" in str(exc)
                    if errors >= SEND_ERRORS_BEFORE_REOPEN or closed:
                        self._counts.add("bus_lost", error=f"bus lost: {exc}")
                        self._status.set(LinkState.LOST, str(exc))
                        _shutdown(bus)
                        bus = None
                    continue
                errors = 0
                self._counts.add("sent")
                if writer is not None:
                    writer.on_message_received(frame)
                    if self._queue.empty():
                        writer.file.flush()
        finally:
            if bus is not None:
                _shutdown(bus)
            if writer is not None:
                writer.stop()

    def _open(self) -> can.BusABC | None:
        try:
            bus = self._factory(self.interface, self.channel, None, **self._bus_kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            why = open_error(self.interface, self.channel, exc)
            self._counts.add("open_failures", error=why)
            self._status.set(LinkState.LOST, why)
            return None
        self._counts.add("opens")
        self._backoff.reset()
        self._status.set(LinkState.OK)
        return bus


def _shutdown(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except (can.CanError, OSError) as exc:
        log.debug("shutdown of a failed bus: %s", exc)
