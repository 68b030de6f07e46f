"""One command/reply exchange at a time with a PTU-D46 over an open serial port.

:class:`PtuLink` sends a command and waits for its ``*`` reply within a deadline,
retrying after a timeout; it drops garbage lines (and flushes the input before the
next command), counts unsolicited limit events, and recognises a unit that was
reset (banner, echo or verbose text in normal operation) by raising
:class:`UnitReset`. :func:`handshake` runs the init sequence of the reference notes
and returns what the unit reported. Port errors (``SerialException``/``OSError``)
pass through to the owner of the port. Counts go to a shared
:class:`~drivers.link.Counters`.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass

import serial

from drivers.link import Counters
from drivers.ptu_protocol import (
    PtuProtocolError,
    Reply,
    ReplyKind,
    ReplyParser,
    encode_command,
    parse_float,
    parse_int,
)


class PtuCommandError(Exception):
    """The unit answered ``!`` (text in the message)."""


class NoReply(Exception):
    """No ``*`` reply within the deadline, after all retries."""


class UnitReset(Exception):
    """The unit shows factory state (banner, echo, verbose): run the handshake again."""


class PtuInitError(Exception):
    """The init handshake failed (no answer, an error reply, or implausible values)."""


@dataclass(frozen=True)
class UnitInfo:
    """What the unit reports at init, per axis key ``"P"``/``"T"``.

    resolution_arcsec: arc seconds per step; limits: (min, max) steps; speed_bounds:
    (lower, upper) steps/s.
    """

    resolution_arcsec: dict[str, float]
    limits: dict[str, tuple[int, int]]
    speed_bounds: dict[str, tuple[int, int]]


class PtuLink:
    """Exchanges on ``port`` (opened by the caller, read timeout <= ``timeout_s``)."""

    def __init__(self, port: serial.SerialBase, timeout_s: float = 0.2, retries: int = 1,
                 counters: Counters | None = None) -> None:
        self.port = port
        self.timeout_s = timeout_s
        self.retries = retries
        self.counts = counters if counters is not None else Counters()
        self._parser = ReplyParser()
        self._replies: deque[Reply] = deque()
        self._dirty = False

    def flush(self) -> None:
        """Discard unread input and any partial line."""
        self.port.reset_input_buffer()
        self._parser.reset()
        self._replies.clear()
        self._dirty = False

    def transact(self, op: str, arg: int | None = None, *, during_init: bool = False) -> Reply:
        """Send ``op[arg]`` and return its ``*`` reply (retried after a timeout).

        Raises :class:`PtuCommandError` on a ``!`` reply (never retried),
        :class:`NoReply` after ``retries + 1`` timeouts, :class:`UnitReset` on evidence
        of a reset (outside ``during_init``).
        """
        data = encode_command(op, arg)
        sent = data.decode().strip()
        for _ in range(self.retries + 1):
            if self._dirty:
                self.flush()
            self.port.write(data)
            reply = self._await_reply(sent, time.monotonic() + self.timeout_s, during_init)
            if reply is not None:
                return reply
            self.counts.add("timeouts", error=f"no reply to {sent}")
            self._dirty = True
        raise NoReply(f"no reply to {sent} after {self.retries + 1} tries")

    def _await_reply(self, sent: str, deadline: float, during_init: bool) -> Reply | None:
        """The next OK reply to ``sent`` before ``deadline``; None on timeout.

        While echo may still be on (init), an echo of another command marks the reply
        after it as belonging to that command, and it is skipped.
        """
        skip = False
        while True:
            while self._replies:
                r = self._replies.popleft()
                if r.kind in (ReplyKind.OK, ReplyKind.ERROR) and skip:
                    skip = False
                    self.counts.add("stray_replies",
                                    error=f"stray reply {r.text!r} awaiting {sent}")
                elif r.kind is ReplyKind.OK:
                    return r
                elif r.kind is ReplyKind.ERROR:
                    raise PtuCommandError(r.text)
                elif r.kind is ReplyKind.LIMIT:
                    self.counts.add("limit_events", error=f"limit hit on axis {r.text}")
                elif r.kind is ReplyKind.GARBAGE:
                    self.counts.add("garbage", error=f"garbage {r.text}")
                    self._dirty = True
                elif r.kind is ReplyKind.BANNER:
                    self.counts.add("banners")
                    if not during_init:
                        self.counts.add("resets_detected", error=f"banner {r.text!r}")
                        raise UnitReset("unit reset (banner)")
                elif r.kind is ReplyKind.ECHO and during_init:
                    skip = r.text != sent
                elif r.kind is ReplyKind.ECHO:
                    self.counts.add("resets_detected", error=f"echo of {r.text}")
                    raise UnitReset("unit reset (echo is on again)")
            if time.monotonic() >= deadline:
                return None
            chunk = self.port.read(max(1, self.port.in_waiting))
            if chunk:
                self._replies.extend(self._parser.feed(chunk))


def handshake(link: PtuLink) -> UnitInfo:
    """Init: ``ED FT CI I`` (each drained), then ``PR TR``, ``PN PX TN TX``, ``PL PU TL TU``."""
    link.flush()
    try:
        for op in ("ED", "FT", "CI", "I"):
            link.transact(op, during_init=True)
        res = {k: parse_float(link.transact(f"{k}R", during_init=True)) for k in "PT"}
        lim = {k: (parse_int(link.transact(f"{k}N", during_init=True)),
                   parse_int(link.transact(f"{k}X", during_init=True))) for k in "PT"}
        spd = {k: (parse_int(link.transact(f"{k}L", during_init=True)),
                   parse_int(link.transact(f"{k}U", during_init=True))) for k in "PT"}
    except (NoReply, PtuCommandError, PtuProtocolError) as exc:
        raise PtuInitError(str(exc)) from None
    for k in "PT":
        if not res[k] > 0.0 or lim[k][0] >= lim[k][1] or not 0 < spd[k][0] <= spd[k][1]:
            raise PtuInitError(f"implausible {k}: resolution {res[k]} arcsec, limits "
                               f"{lim[k]}, speed bounds {spd[k]}")
    return UnitInfo(res, lim, spd)
