"""Vehicle CAN reader: speed and yaw rate from a python-can bus, on the monotonic clock.

A supervisor thread opens the bus (``interface``/``channel`` as in python-can), runs
a :class:`can.Notifier` with a :class:`can.Listener` that decodes every frame with a
:class:`~drivers.vehicle_signals.VehicleSignalDecoder` and hands each value to
``sink``. Nothing on the wire is raised to the caller; it is counted in ``stats``:

- frames of other ids (``ignored``), of a configured id with the wrong length
  (``wrong_length``) or that cantools cannot decode (``undecodable``);
- error frames (``error_frames``), of which bus-off (``bus_off``, class
  ``CAN_ERR_BUSOFF`` 0x40) also makes the reader reopen the bus;
- a vanished interface (the Notifier reports the receive error): the bus is shut
  down and reopened with exponential back-off (``bus_lost``, ``open_failures``).

Receive filters for the configured ids are installed on the bus where it filters in
the kernel or hardware (SocketCAN and hardware interfaces). ``virtual`` and
``udp_multicast`` filter in Python, which is exactly the reader's own id check, and
would also drop error frames, so no bus filters are set there.

Timestamps: SocketCAN, ``virtual`` and ``udp_multicast`` stamp frames with the wall
clock (``time.time()``, the kernel receive time for SocketCAN). With
``timestamp_clock="wall"`` (default) a frame's time is mapped to the monotonic clock
by the offset ``monotonic() - time()`` measured when it is handled; a result in the
future or more than 1 s old (a wall-clock step) falls back to the handling time
(``timestamp_fallbacks``). ``"monotonic"`` trusts the bus's stamps as they are;
``"receive"`` always uses the handling time.

Staleness: a signal older than ``stale_s`` is stale; :meth:`VehicleCanReader.state_at`
is the pure rule and the supervisor publishes it as :attr:`state` every
``stale_s / 4``.
"""

from __future__ import annotations

import copy
import errno
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import can

from drivers.backoff import Backoff
from drivers.link import Counters, LinkState, LinkStatus, Reporting
from drivers.vehicle_signals import (
    FrameDecodeError,
    SignalKind,
    VehicleCanConfigError,
    VehicleSignal,
    VehicleSignalDecoder,
)

__all__ = ["VehicleCanReader", "VehicleCanStats", "VehicleSignalDecoder", "VehicleSignal",
           "SignalKind", "VehicleCanConfigError", "FrameDecodeError", "open_bus", "open_error"]

log = logging.getLogger(__name__)

CAN_ERR_BUSOFF = 0x40
SOFTWARE_FILTER_INTERFACES = frozenset({"virtual", "udp_multicast"})
MAX_TIMESTAMP_AGE_S = 1.0


@dataclass(frozen=True)
class VehicleCanStats:
    frames: int = 0
    decoded: int = 0
    ignored: int = 0
    wrong_length: int = 0
    undecodable: int = 0
    error_frames: int = 0
    bus_off: int = 0
    bus_lost: int = 0
    opens: int = 0
    open_failures: int = 0
    timestamp_fallbacks: int = 0
    sink_errors: int = 0
    last_error: str = ""


BusFactory = Callable[..., can.BusABC]


def open_bus(interface: str, channel: str, can_filters: list[dict[str, Any]] | None,
             **kwargs: Any) -> can.BusABC:
    """``can.Bus`` with the given filters (the default bus factory of the CAN drivers)."""
    return can.Bus(interface=interface, channel=channel, can_filters=can_filters, **kwargs)


def open_error(interface: str, channel: str, exc: BaseException) -> str:
    """Why a bus did not open, with the likely cause of the SocketCAN errors users meet."""
    text = f"cannot open {interface}:{channel}: {exc}"
    if interface != "socketcan":
        return text
    code = next((e.errno for e in (exc, exc.__cause__, exc.__context__)
                 if isinstance(e, OSError) and e.errno is not None), None)
    hint = {
        errno.EAFNOSUPPORT: "this kernel has no SocketCAN (sudo modprobe can can-raw; "
                            "containers and WSL kernels often lack it)",
        errno.ENODEV: f"no network interface {channel} (ip link show {channel}: is the adapter "
                      f"plugged in? a virtual bus: sudo ip link add dev {channel} type vcan)",
        errno.ENETDOWN: f"{channel} is down (sudo ip link set {channel} up, with its bitrate)",
    }.get(code) if code is not None else None
    return f"{text}: {hint}" if hint else text


class _Listener(can.Listener):
    def __init__(self, reader: VehicleCanReader) -> None:
        self._reader = reader

    def on_message_received(self, msg: can.Message) -> None:
        self._reader._on_frame(msg)

    def on_error(self, exc: Exception) -> None:
        self._reader._on_bus_error(exc)

    def stop(self) -> None:
        pass


class VehicleCanReader(Reporting[VehicleCanStats]):
    """Reads the vehicle bus; see the module docstring.

    :param decoder: the vehicle's DBC and signal names.
    :param sink: called on the Notifier thread with every :class:`VehicleSignal`; must
        not block.
    :param bus_kwargs: extra arguments for ``can.Bus`` (e.g. ``port`` for udp_multicast).
    :param bus_factory: ``(interface, channel, can_filters, **bus_kwargs) -> BusABC``.
    :param raw_sink: called on the Notifier thread with every received frame (a copy
        whose ``timestamp`` is on the monotonic clock), e.g. to record the drive; must
        not block.
    """

    def __init__(self, decoder: VehicleSignalDecoder, *, interface: str = "socketcan",
                 channel: str = "can0", stale_s: float = 0.2, reopen_min_s: float = 0.5,
                 reopen_max_s: float = 5.0, sink: Callable[[VehicleSignal], None] | None = None,
                 timestamp_clock: str = "wall", bus_kwargs: dict[str, Any] | None = None,
                 bus_factory: BusFactory = open_bus,
                 raw_sink: Callable[[can.Message], None] | None = None) -> None:
        if timestamp_clock not in ("wall", "monotonic", "receive"):
            raise ValueError(
                f"timestamp_clock {timestamp_clock!r} is not wall, monotonic or receive")
        if not stale_s > 0.0:
            raise ValueError(f"stale_s must be > 0, got {stale_s}")
        self.decoder = decoder
        self.interface = interface
        self.channel = channel
        self.stale_s = stale_s
        self._sink = sink
        self._raw_sink = raw_sink
        self._clock_mode = timestamp_clock
        self._bus_kwargs = dict(bus_kwargs or {})
        self._factory = bus_factory
        self._backoff = Backoff(reopen_min_s, reopen_max_s)
        self._status = LinkStatus(f"vehicle CAN {interface}:{channel}", log)
        self._counts = Counters()
        self._stats_type = VehicleCanStats
        self._latest: dict[SignalKind, VehicleSignal] = {}
        self._stop = threading.Event()
        self._lost = threading.Event()
        self._lost_ack = threading.Event()
        self._lost_why = ""
        self._bus_up = False
        self._thread: threading.Thread | None = None

    # ---------------------------------------------------------------- public

    def start(self) -> VehicleCanReader:
        self._thread = threading.Thread(target=self._supervise, name="vehicle-can", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self._lost_ack.set()
        if self._thread is not None:
            self._thread.join(timeout)
        self._status.set(LinkState.STOPPED)

    def __enter__(self) -> VehicleCanReader:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def latest(self, kind: SignalKind) -> VehicleSignal | None:
        """The newest value of ``kind``, or None if none was received yet."""
        return self._latest.get(kind)

    def state_at(self, now: float) -> LinkState:
        """LOST while the bus is down; STALE if a signal is missing or older than stale_s."""
        if self._status.state is LinkState.STOPPED:
            return LinkState.STOPPED
        if not self._bus_up:
            return LinkState.LOST if self._status.state is LinkState.LOST else self._status.state
        return freshness(self._latest, now, self.stale_s)

    # ---------------------------------------------------------------- notifier thread

    def _on_frame(self, msg: can.Message) -> None:
        count = self._counts.add
        count("frames")
        if self._raw_sink is not None:
            raw = copy.copy(msg)
            raw.timestamp = self._monotonic_time(msg.timestamp)
            try:
                self._raw_sink(raw)
            except Exception as exc:  # the consumer's bug must not stop the reader
                count("sink_errors", error=f"raw sink: {type(exc).__name__}: {exc}")
        if msg.is_error_frame:
            count("error_frames", error=f"error frame class 0x{msg.arbitration_id:X}")
            if msg.arbitration_id & CAN_ERR_BUSOFF:
                count("bus_off", error="bus-off")
                self._signal_lost("bus-off")
            return
        if msg.is_remote_frame or not self.decoder.wants(msg.arbitration_id, msg.is_extended_id):
            count("ignored")
            return
        t = self._monotonic_time(msg.timestamp)
        try:
            values = self.decoder.decode(msg.arbitration_id, msg.data, t, msg.is_extended_id)
        except FrameDecodeError as exc:
            count(exc.reason, error=str(exc))
            return
        count("decoded")
        for value in values:
            self._latest[value.kind] = value
        if self._status.state is not LinkState.OK and self._bus_up and not self._lost.is_set() \
                and freshness(self._latest, time.monotonic(), self.stale_s) is LinkState.OK:
            self._status.set(LinkState.OK)
        if self._sink is not None:
            for value in values:
                try:
                    self._sink(value)
                except Exception as exc:  # the consumer's bug must not stop the reader
                    count("sink_errors", error=f"sink: {type(exc).__name__}: {exc}")

    def _monotonic_time(self, stamp: float) -> float:
        now = time.monotonic()
        if self._clock_mode == "receive":
            return now
        t = stamp + (now - time.time()) if self._clock_mode == "wall" else stamp
        if not now - MAX_TIMESTAMP_AGE_S <= t <= now + 1e-3:
            self._counts.add("timestamp_fallbacks")
            return now
        return t

    def _on_bus_error(self, exc: Exception) -> None:
        """The Notifier's receive failed: hand over to the supervisor and park."""
        self._signal_lost(f"{type(exc).__name__}: {exc}")
        self._lost_ack.wait(5.0)   # the supervisor stops the Notifier, then releases us

    def _signal_lost(self, why: str) -> None:
        if not self._lost.is_set():
            self._lost_why = why
            self._lost.set()

    # ---------------------------------------------------------------- supervisor

    def _supervise(self) -> None:
        while not self._stop.is_set():
            bus, notifier = self._open()
            if bus is None or notifier is None:
                self._stop.wait(self._backoff.next_delay())
                continue
            while not self._stop.is_set() and not self._lost.is_set():
                self._status.set(freshness(self._latest, time.monotonic(), self.stale_s))
                if self._lost.wait(self.stale_s / 4.0):
                    break
            self._bus_up = False
            if self._lost.is_set() and not self._stop.is_set():
                self._counts.add("bus_lost", error=f"bus lost: {self._lost_why}")
                self._status.set(LinkState.LOST, self._lost_why)
            self._close(bus, notifier)
            if not self._stop.is_set():
                self._stop.wait(self._backoff.next_delay())

    def _open(self) -> tuple[can.BusABC | None, can.Notifier | None]:
        filters = None if self.interface in SOFTWARE_FILTER_INTERFACES else \
            self.decoder.can_filters()
        try:
            bus = self._factory(self.interface, self.channel, filters, **self._bus_kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            why = open_error(self.interface, self.channel, exc)
            self._counts.add("open_failures", error=why)
            self._status.set(LinkState.LOST, why)
            return None, None
        self._counts.add("opens")
        self._lost.clear()
        self._lost_ack.clear()
        self._backoff.reset()
        self._bus_up = True
        return bus, can.Notifier(bus, [_Listener(self)], timeout=0.05)

    def _close(self, bus: can.BusABC, notifier: can.Notifier) -> None:
        notifier.stop(timeout=0.0)    # ends the receive loop at its next turn...
        self._lost_ack.set()          # ...including a thread parked in _on_bus_error
        notifier.stop(timeout=1.0)
        try:
            bus.shutdown()
        except (can.CanError, OSError) as exc:
            log.debug("shutdown of a lost bus: %s", exc)


def freshness(latest: dict[SignalKind, VehicleSignal], now: float, stale_s: float) -> LinkState:
    """OK if speed and yaw rate were both received within ``stale_s`` of ``now``."""
    for kind in SignalKind:
        value = latest.get(kind)
        if value is None or now - value.t > stale_s:
            return LinkState.STALE
    return LinkState.OK
