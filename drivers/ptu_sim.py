"""A simulated PTU-D46 on a real pseudo-terminal (``collision-warning ptu-sim``).

The simulator opens a pty with :func:`os.openpty`, puts it in raw mode and speaks
the unit's ASCII protocol on the master side, using ``ptu_protocol`` from the other
side. The driver (or any terminal program) opens the slave, ``device``, or the
symlink ``link`` which is re-pointed when the simulated cable is re-plugged, like
the udev rule's ``/dev/cw-ptu``.

Behaviour: factory state on power-up and ``reset()`` (echo on, verbose feedback, a
banner), limits and resolution of a PTU-D46-17, axes that move with limited speed
and acceleration (``ptu_axis.advance``), and the wire time of each exchange at the
baud rate the host set on the pty. Faults to inject (``PtuFaults``): reply latency,
garbage bursts, error replies, dropped replies, silence, replies split in two writes,
unsolicited limit events, disconnect (the master is closed) and reconnect.
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import sys
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from drivers.ptu_protocol import CommandParser, Reply, ReplyKind, format_reply
from drivers.ptu_unit import UnitModel

BANNER = (
    "### PAN-TILT CONTROLLER (simulated PTU-D46-17)",
    "### (c) collision-warning test bench, protocol of the PTU-D46 user's manual v2.14",
    "Initializing...",
)
_BAUDS = {getattr(termios, f"B{b}"): b for b in
          (600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)}


@dataclass(frozen=True)
class PtuFaults:
    """Fault knobs; probabilities are per reply, drawn from the simulator's seeded RNG."""

    latency_s: float = 0.0   # s, controller turnaround added to every reply
    garbage: float = 0.0     # probability of a burst of non-ASCII bytes + CR LF before a reply
    error: float = 0.0       # probability of answering '! Axis Error' instead of executing
    drop: float = 0.0        # probability of executing a command without replying
    silent: bool = False     # execute nothing, answer nothing (a hung controller)
    split: bool = False      # write each reply in two parts, 2 ms apart


@dataclass(frozen=True)
class SimStats:
    commands: int = 0
    replies: int = 0
    garbage_bursts: int = 0
    errors_injected: int = 0
    dropped: int = 0
    disconnects: int = 0
    resets: int = 0


class PtuSimulator:
    """The simulated unit; ``start()`` opens the pty, ``stop()`` closes it.

    :param link: optional path of a symlink to the current pty slave.
    :param seed: seed of the fault RNG.
    :param faults: initial fault knobs.
    :param emulate_wire_time: delay each reply by the wire time of command plus reply
        at the baud rate read from the pty's termios (what the host configured).
    """

    def __init__(self, link: str | Path | None = None, *, seed: int = 0,
                 faults: PtuFaults = PtuFaults(), emulate_wire_time: bool = True,
                 reset_duration_s: float = 0.2) -> None:
        self.link = Path(link) if link is not None else None
        self._rng = np.random.default_rng(seed)
        self._faults = faults
        self._wire = emulate_wire_time
        self.unit = UnitModel(reset_duration_s=reset_duration_s)
        self._parser = CommandParser()
        self._master = -1
        self._slave = -1
        self.device = ""
        self._out: list[tuple[float, bytes]] = []   # (due time, bytes), due times non-decreasing
        self._calls: list[tuple[Callable[[], None], threading.Event]] = []
        self._lock = threading.Lock()
        self._wake_r, self._wake_w = os.pipe()
        self._stopping = threading.Event()
        self._thread: threading.Thread | None = None
        self._stats = SimStats()
        self.received: deque[str] = deque(maxlen=10000)
        """Command tokens received, newest last (for tests and the console)."""

    # ---------------------------------------------------------------- control

    @property
    def port(self) -> str:
        """What the host should open: the link if there is one, else the pty slave."""
        return str(self.link) if self.link is not None else self.device

    @property
    def stats(self) -> SimStats:
        return self._stats

    @property
    def faults(self) -> PtuFaults:
        return self._faults

    def set_faults(self, **knobs: float | bool) -> None:
        """Change fault knobs (names of :class:`PtuFaults`) while running."""
        self._faults = replace(self._faults, **knobs)  # type: ignore[arg-type]

    def start(self) -> PtuSimulator:
        self._open_pty()
        self.unit.power_up(time.monotonic())
        self._emit_banner(time.monotonic())
        self._thread = threading.Thread(target=self._run, name="ptu-sim", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop and release the pseudo-terminal; a second call does nothing."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(5.0)
        self._close_pty()
        if self.link is not None and self.link.is_symlink():
            self.link.unlink()
        os.close(self._wake_r)
        os.close(self._wake_w)

    def __enter__(self) -> PtuSimulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def disconnect(self) -> None:
        """Unplug: close the pty master (the host's reads and writes fail with EIO)."""
        self._call(self._do_disconnect)

    def reconnect(self, power_cycle: bool = False) -> None:
        """Re-plug: a new pty (the link follows it); ``power_cycle`` also resets the unit."""
        self._call(lambda: self._do_reconnect(power_cycle))

    def reset(self) -> None:
        """Power-cycle the unit in place: factory state (echo, verbose) and a banner."""
        self._call(self._do_reset)

    def emit_limit(self, axis: str) -> None:
        """Send an unsolicited ``!P`` or ``!T`` as when an axis hits its limit."""
        self._call(lambda: self._queue(time.monotonic(),
                                       format_reply(Reply(ReplyKind.LIMIT, axis))))

    def position_steps(self) -> tuple[float, float]:
        """True (pan, tilt) position now, steps (for tests)."""
        result: list[tuple[float, float]] = []
        self._call(lambda: result.append(self.unit.position(time.monotonic())))
        return result[0]

    # ---------------------------------------------------------------- sim thread

    def _call(self, fn: Callable[[], None]) -> None:
        done = threading.Event()
        with self._lock:
            self._calls.append((fn, done))
        os.write(self._wake_w, b"x")
        if not done.wait(5.0):
            raise TimeoutError("PTU simulator thread did not respond")

    def _run(self) -> None:
        while not self._stopping.is_set():
            now = time.monotonic()
            timeout = 0.5 if not self._out else max(0.0, self._out[0][0] - now)
            fds = [self._wake_r] + ([self._master] if self._master >= 0 else [])
            readable, _, _ = select.select(fds, [], [], timeout)
            if self._wake_r in readable:
                os.read(self._wake_r, 1024)
                with self._lock:
                    calls, self._calls = self._calls, []
                for fn, done in calls:
                    fn()
                    done.set()
            if self._master >= 0 and self._master in readable:
                try:
                    data = os.read(self._master, 4096)
                except OSError:   # no slave open at the moment: nothing to read
                    data = b""
                for cmd in self._parser.feed(data):
                    self._handle(cmd.raw, time.monotonic())
            self._flush(time.monotonic())

    def _handle(self, raw: str, now: float) -> None:
        faults = self._faults
        self.received.append(raw)
        self._stats = replace(self._stats, commands=self._stats.commands + 1)
        if faults.silent:
            return
        if faults.error and self._rng.random() < faults.error:
            self._stats = replace(self._stats, errors_injected=self._stats.errors_injected + 1)
            answer = self.unit.answer_error(raw, "Axis Error")
        else:
            answer = self.unit.execute(raw, now)
        if faults.drop and self._rng.random() < faults.drop:
            self._stats = replace(self._stats, dropped=self._stats.dropped + 1)
            return
        due = now + answer.delay_s + faults.latency_s
        if self._wire:
            due += (len(raw) + 1 + len(answer.data)) * 10.0 / self._baud()
        if faults.garbage and self._rng.random() < faults.garbage:
            self._stats = replace(self._stats, garbage_bursts=self._stats.garbage_bursts + 1)
            burst = self._rng.integers(0x80, 0x100, size=int(self._rng.integers(1, 17)))
            self._queue(due, bytes(burst.astype(np.uint8)) + b"\r\n")
        if faults.split and len(answer.data) > 1:
            cut = len(answer.data) // 2
            self._queue(due, answer.data[:cut])
            self._queue(due + 0.002, answer.data[cut:])
        else:
            self._queue(due, answer.data)
        self._stats = replace(self._stats, replies=self._stats.replies + 1)

    def _queue(self, due: float, data: bytes) -> None:
        if self._out:
            due = max(due, self._out[-1][0])
        self._out.append((due, data))

    def _flush(self, now: float) -> None:
        while self._out and self._out[0][0] <= now:
            _, data = self._out.pop(0)
            if self._master >= 0:
                try:
                    os.write(self._master, data)
                except OSError:
                    pass   # nobody reading: the bytes are lost, as on a real line

    def _baud(self) -> int:
        try:
            return _BAUDS.get(termios.tcgetattr(self._master)[5], 9600)
        except termios.error:
            return 9600

    def _emit_banner(self, now: float) -> None:
        for line in BANNER:
            self._queue(now, format_reply(Reply(ReplyKind.BANNER, line)))

    def _do_disconnect(self) -> None:
        self._stats = replace(self._stats, disconnects=self._stats.disconnects + 1)
        self._close_pty()
        self._out.clear()
        self._parser = CommandParser()

    def _do_reconnect(self, power_cycle: bool) -> None:
        if self._master < 0:
            self._open_pty()
        if power_cycle:
            self._do_reset()

    def _do_reset(self) -> None:
        self._stats = replace(self._stats, resets=self._stats.resets + 1)
        now = time.monotonic()
        self.unit.power_up(now)
        self._out.clear()
        self._emit_banner(now)

    def _open_pty(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)   # no line discipline: bytes pass unchanged, no kernel echo
        self.device = os.ttyname(self._slave)
        if self.link is not None:
            tmp = self.link.with_name(self.link.name + ".tmp")
            if tmp.is_symlink() or tmp.exists():
                tmp.unlink()
            tmp.symlink_to(self.device)
            os.replace(tmp, self.link)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1


def main(args: argparse.Namespace) -> int:
    """``collision-warning ptu-sim``: print the device path (first line, for scripts) and how to
    use it, run until SIGINT/SIGTERM."""
    faults = PtuFaults(latency_s=float(getattr(args, "latency", 0.0) or 0.0),
                       garbage=float(getattr(args, "garbage", 0.0) or 0.0))
    if faults.latency_s < 0.0 or not 0.0 <= faults.garbage <= 1.0:
        print("ptu-sim: --latency must be >= 0 and --garbage in [0, 1]", file=sys.stderr)
        return 2
    link = getattr(args, "link", None)
    if link is not None and Path(link).exists() and not Path(link).is_symlink():
        print(f"ptu-sim: --link {link}: exists and is not a symlink", file=sys.stderr)
        return 2
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    sim = PtuSimulator(link, seed=int(getattr(args, "seed", 0) or 0), faults=faults)
    try:
        sim.start()
    except OSError as exc:
        print(f"ptu-sim: cannot open a pseudo-terminal or link: {exc}", file=sys.stderr)
        return 1
    print(sim.device + (f" (link {sim.link})" if sim.link is not None else ""), flush=True)
    print(f"simulated PTU-D46 on {sim.port}: set it as the appliance's PTU port in the file "
          f"given to --config,\n  [ptu]\n  port = \"{sim.port}\"\n"
          "or talk to it with a terminal program (any baud rate). Ctrl-C (SIGINT) or SIGTERM "
          "stops it.", flush=True)
    try:
        while not done.wait(0.5):
            pass
    finally:
        sim.stop()
    return 0
