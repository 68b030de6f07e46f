"""Pan-tilt unit driver: PTU-D46 family over a pyserial port.

One thread owns the port. It opens it (a device path, a symlink or any pyserial URL),
runs the init handshake, then polls the position at ``poll_hz`` and hands each
:class:`PtuSample` (monotonic time, radians in the spec's convention) to ``sink``;
moves and speed changes requested with :meth:`PtuDriver.move_to` /
:meth:`PtuDriver.set_speed` are sent between polls. Nothing the unit or the line
does is raised to the caller: it is counted in :attr:`PtuDriver.stats` and shown in
:attr:`PtuDriver.state`.

Following the reference notes (section 5 "Copy"/"Fix", section 7):

- init: ``ED`` (echo off), ``FT`` (terse), ``CI`` (position mode), ``I`` (immediate),
  each drained on its own; ``PR``/``TR`` resolution, ``PN PX TN TX`` limits, ``PL PU TL
  TU`` speed bounds read from the unit; ``PS``/``TS`` the configured speed, clamped to
  the bounds. Init fails (and the port is reopened with back-off) if any step fails;
- replies are classified by their first character; garbage lines are dropped and
  counted, and the input is flushed before the next command; a reply missing after
  ``timeout_s`` is retried ``retries`` times; ``!`` replies are errors, never retried;
- an echo, verbose text or a banner in normal operation means the unit was reset:
  the handshake is run again; ``fault_after`` consecutive failed polls set the state
  to STALE (the appliance's PTU fault) and trigger a new handshake;
- a vanished port (SerialException / OSError, e.g. EIO from an unplugged adapter)
  is closed and reopened with exponential back-off;
- radians <-> steps: ``rad = sign * steps * PR * pi / (180 * 3600) + offset``, and
  back with ``round()``; moves are checked against the limits read from the unit.

A sample's time is the midpoint between sending ``PP`` and receiving the ``TP``
reply (the unit reads its encoders somewhere in that window; at 115200 baud it is
about 1 ms wide plus the controller's turnaround).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import serial

from drivers.backoff import Backoff
from drivers.link import Counters, LinkState, LinkStatus, Reporting
from drivers.ptu_link import (
    NoReply,
    PtuCommandError,
    PtuInitError,
    PtuLink,
    UnitReset,
    handshake,
)
from drivers.ptu_protocol import PtuProtocolError, parse_int

__all__ = ["PtuDriver", "PtuSample", "PtuStats", "AxisCalibration", "PtuLimitError",
           "PtuCommandError", "PtuInitError", "open_serial"]

log = logging.getLogger(__name__)

ARCSEC = math.pi / (180.0 * 3600.0)   # rad per arc second


@dataclass(frozen=True)
class PtuSample:
    """Measured position: ``t`` monotonic s; pan left +, tilt up +, rad (spec convention)."""

    t: float
    pan_rad: float
    tilt_rad: float


@dataclass(frozen=True)
class PtuStats:
    """Counters since ``start()``; ``last_error`` is the latest problem, for the log."""

    samples: int = 0
    timeouts: int = 0
    garbage: int = 0
    error_replies: int = 0
    limit_events: int = 0
    banners: int = 0
    resets_detected: int = 0
    unresponsive: int = 0
    init_failures: int = 0
    open_failures: int = 0
    port_lost: int = 0
    opens: int = 0
    moves: int = 0
    rejected_moves: int = 0
    unanswered_commands: int = 0
    stray_replies: int = 0
    sink_errors: int = 0
    last_error: str = ""


@dataclass(frozen=True)
class AxisCalibration:
    """Steps <-> radians for one axis, from the unit's resolution and limits.

    ``rad = sign * steps * rad_per_step + offset_rad``; ``lo``/``hi`` in steps.
    """

    rad_per_step: float
    sign: int
    offset_rad: float
    lo: int
    hi: int

    def to_rad(self, steps: int) -> float:
        return self.sign * steps * self.rad_per_step + self.offset_rad

    def to_steps(self, rad: float) -> int:
        return round((rad - self.offset_rad) / (self.sign * self.rad_per_step))

    def limits_rad(self) -> tuple[float, float]:
        a, b = self.to_rad(self.lo), self.to_rad(self.hi)
        return (min(a, b), max(a, b))


class PtuLimitError(ValueError):
    """A requested move lies outside the limits the unit reported."""


SerialFactory = Callable[[str, int, float], serial.SerialBase]


def open_serial(port: str, baud: int, timeout: float) -> serial.SerialBase:
    """A device path or symlink (opened exclusively) or any pyserial URL (``loop://``...)."""
    if "://" in port:
        return serial.serial_for_url(port, baudrate=baud, timeout=timeout)
    return serial.Serial(port, baudrate=baud, timeout=timeout, exclusive=True)


class PtuDriver(Reporting[PtuStats]):
    """The PTU driver thread. Parameters are plain values (see config ``[ptu]``).

    :param port: device path, symlink or pyserial URL.
    :param sink: called on the driver thread with every :class:`PtuSample`; must not block.
    :param serial_factory: ``(port, baud, read_timeout_s) -> SerialBase``; default
        :func:`open_serial`.
    """

    def __init__(self, port: str, *, baud: int = 9600, pan_sign: int = 1, tilt_sign: int = 1,
                 pan_offset_rad: float = 0.0, tilt_offset_rad: float = 0.0,
                 poll_hz: float = 20.0, timeout_s: float = 0.2, retries: int = 1,
                 speed_rad_s: float = 1.0, reopen_min_s: float = 0.5, reopen_max_s: float = 5.0,
                 fault_after: int = 3, sink: Callable[[PtuSample], None] | None = None,
                 serial_factory: SerialFactory = open_serial) -> None:
        if pan_sign not in (1, -1) or tilt_sign not in (1, -1):
            raise ValueError("pan_sign and tilt_sign must be +1 or -1")
        if poll_hz <= 0.0 or timeout_s <= 0.0 or retries < 0 or fault_after < 1:
            raise ValueError("poll_hz and timeout_s must be > 0, retries >= 0, fault_after >= 1")
        self.port_name = port
        self._baud = baud
        self._signs = {"P": pan_sign, "T": tilt_sign}
        self._offsets = {"P": pan_offset_rad, "T": tilt_offset_rad}
        self._period = 1.0 / poll_hz
        self._timeout = timeout_s
        self._retries = retries
        self._fault_after = fault_after
        self._sink = sink
        self._factory = serial_factory
        self._backoff = Backoff(reopen_min_s, reopen_max_s)
        self._status = LinkStatus(f"PTU {port}", log)
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._lock = threading.Lock()
        self._counts = Counters()
        self._stats_type = PtuStats
        self._latest: PtuSample | None = None
        self._cal: dict[str, AxisCalibration] = {}
        self._speed_bounds: dict[str, tuple[int, int]] = {}
        self._want_speed: float | None = speed_rad_s
        self._last_speed: float | None = None
        self._want_move: tuple[float, float] | None = None
        self._link: PtuLink | None = None
        self._thread: threading.Thread | None = None

    # ---------------------------------------------------------------- public

    def start(self) -> PtuDriver:
        self._thread = threading.Thread(target=self._run, name="ptu", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)
        self._status.set(LinkState.STOPPED)

    def __enter__(self) -> PtuDriver:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


    @property
    def latest(self) -> PtuSample | None:
        """The newest sample, or None before the first one."""
        return self._latest

    @property
    def limits_rad(self) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """((pan_min, pan_max), (tilt_min, tilt_max)) in rad once the unit reported them."""
        cal = self._cal
        if "P" not in cal or "T" not in cal:
            return None
        return cal["P"].limits_rad(), cal["T"].limits_rad()

    def move_to(self, pan_rad: float, tilt_rad: float) -> None:
        """Request an absolute move (non-blocking; sent before the next poll).

        Raises :class:`PtuLimitError` if the target is outside the limits the unit
        reported; before those are known the check happens when the move is sent
        (a rejected move is counted in ``stats.rejected_moves``).
        """
        cal = self._cal
        for key, rad in (("P", pan_rad), ("T", tilt_rad)):
            if not math.isfinite(rad):
                raise PtuLimitError(f"PTU target {rad} rad is not finite")
            if key in cal and not cal[key].lo <= cal[key].to_steps(rad) <= cal[key].hi:
                lo, hi = cal[key].limits_rad()
                name = "pan" if key == "P" else "tilt"
                raise PtuLimitError(f"PTU {name} target {rad:.4f} rad outside [{lo:.4f}, {hi:.4f}]")
        with self._lock:
            self._want_move = (pan_rad, tilt_rad)
        self._wake.set()

    def set_speed(self, rad_s: float) -> None:
        """Request a new speed for moves, rad/s (clamped to the unit's bounds)."""
        if not rad_s > 0.0:
            raise ValueError(f"PTU speed must be > 0 rad/s, got {rad_s}")
        with self._lock:
            self._want_speed = rad_s
        self._wake.set()

    # ---------------------------------------------------------------- thread

    def _count(self, name: str, error: str = "") -> None:
        self._counts.add(name, error=error)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                port = self._factory(self.port_name, self._baud, min(0.05, self._timeout / 4.0))
            except (serial.SerialException, OSError, ValueError) as exc:
                self._count("open_failures", f"open {self.port_name}: {exc}")
                self._status.set(LinkState.LOST, f"cannot open {self.port_name}: {exc}")
            else:
                self._count("opens")
                self._session(port)
            if self._stop.is_set():
                break
            self._stop.wait(self._backoff.next_delay())

    def _session(self, port: serial.SerialBase) -> None:
        """Handshake and poll until stop or failure; always closes the port."""
        self._link = PtuLink(port, self._timeout, self._retries, self._counts)
        try:
            while not self._stop.is_set():
                try:
                    self._initialise(self._link)
                    self._backoff.reset()
                    self._poll_loop(self._link)
                except UnitReset as exc:
                    self._status.set(LinkState.STALE, str(exc))
        except (serial.SerialException, OSError) as exc:
            self._count("port_lost", f"port {self.port_name}: {exc}")
            self._status.set(LinkState.LOST, f"port lost: {exc}")
        except PtuInitError as exc:
            self._count("init_failures", f"init: {exc}")
            self._status.set(LinkState.LOST, f"init failed: {exc}")
        finally:
            self._link = None
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass   # already gone

    def _initialise(self, link: PtuLink) -> None:
        info = handshake(link)
        self._cal = {k: AxisCalibration(info.resolution_arcsec[k] * ARCSEC, self._signs[k],
                                        self._offsets[k], *info.limits[k]) for k in "PT"}
        self._speed_bounds = info.speed_bounds
        with self._lock:
            if self._want_speed is None and self._last_speed is not None:
                self._want_speed = self._last_speed   # the unit forgot it on reset

    def _poll_loop(self, link: PtuLink) -> None:
        failures = 0
        next_t = time.monotonic()
        while not self._stop.is_set():
            self._send_requests(link)
            try:
                t0 = time.monotonic()
                pan = parse_int(link.transact("PP"))
                tilt = parse_int(link.transact("TP"))
                t1 = time.monotonic()
            except PtuProtocolError as exc:   # verbose text: the unit was reset
                self._count("resets_detected", str(exc))
                raise UnitReset(f"unit reset ({exc})") from None
            except (NoReply, PtuCommandError) as exc:
                failures += 1
                if isinstance(exc, PtuCommandError):
                    self._count("error_replies", f"position query: ! {exc}")
                if failures >= self._fault_after:
                    self._count("unresponsive", f"{failures} position queries failed")
                    raise UnitReset(f"{failures} position queries failed") from None
            else:
                failures = 0
                sample = PtuSample(0.5 * (t0 + t1), self._cal["P"].to_rad(pan),
                                   self._cal["T"].to_rad(tilt))
                self._latest = sample
                self._count("samples")
                self._status.set(LinkState.OK)
                if self._sink is not None:
                    try:
                        self._sink(sample)
                    except Exception as exc:  # the consumer's bug must not stop the PTU
                        self._count("sink_errors", f"sink: {type(exc).__name__}: {exc}")
            now = time.monotonic()
            next_t = max(next_t + self._period, now)
            self._wake.wait(next_t - now)
            self._wake.clear()

    def _send_requests(self, link: PtuLink) -> None:
        with self._lock:
            speed, self._want_speed = self._want_speed, None
            move, self._want_move = self._want_move, None
        if speed is not None:
            self._last_speed = speed
            for k in "PT":
                lo, hi = self._speed_bounds[k]
                speed_steps = min(hi, max(lo, round(speed / self._cal[k].rad_per_step)))
                self._command(link, f"{k}S", speed_steps, "speed")
        if move is not None:
            steps = {k: self._cal[k].to_steps(rad) for k, rad in zip("PT", move)}
            if any(not self._cal[k].lo <= steps[k] <= self._cal[k].hi for k in "PT"):
                self._count("rejected_moves", f"move {move} rad outside the limits")
                return
            self._count("moves")
            for k in "PT":
                if not self._command(link, f"{k}P", steps[k], "move"):
                    self._count("rejected_moves")

    def _command(self, link: PtuLink, op: str, arg: int, what: str) -> bool:
        """Send a setting; an error reply or no reply is counted, not retried again."""
        try:
            link.transact(op, arg)
            return True
        except PtuCommandError as exc:
            self._count("error_replies", f"{what} {op}{arg}: ! {exc}")
        except NoReply as exc:
            self._count("unanswered_commands", f"{what} {op}{arg}: {exc}")
        return False
