"""ASCII protocol of the FLIR / Directed Perception PTU-D46 family: bytes <-> messages.

Pure: never touches a port. The driver (``ptu.py``) encodes commands and feeds the
bytes it reads to a :class:`ReplyParser`; the simulator (``ptu_sim.py``) feeds the
bytes it receives to a :class:`CommandParser` and formats its answers with
:func:`format_reply`. Conventions (reference notes, [M46] 4.2):

- a command is letters plus an optional signed integer, ended by a space or CR
  (``PP``, ``PP-500``, ``PS1000``); the driver ends every command with a space;
- a success is ``*`` (a query: ``* <value>``), a failure ``! <message>``; replies end
  with CR LF (a bare CR or LF is accepted too, empty lines are skipped);
- ``!P`` / ``!T`` arrive unsolicited when an axis hits a limit (and ``!T!T!P!P*``
  after a reset); a power-up or reset prints a banner (``### PAN-TILT ...``);
- with echo on (the factory default) the command comes back before its reply, on
  the same line (``PP * 100``) or on a line of its own.

Replies are classified by their first character only; a line that is neither a
reply, a limit event, a banner nor the echo of a known command is garbage.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass

LINE_END = b"\r\n"
MAX_LINE = 256
"""Bytes; a longer line without a terminator is cut and reported as garbage."""
MAX_TOKEN = 32
"""Characters; a longer command token is cut and reported as invalid."""

# Every command of the family the simulator understands (reference notes, section 3).
KNOWN_OPS = frozenset({
    "PP", "TP", "PO", "TO", "PR", "TR", "PN", "PX", "TN", "TX", "L", "LE", "LD",
    "PS", "TS", "PA", "TA", "PB", "TB", "PU", "PL", "TU", "TL", "CI", "CV", "C",
    "I", "S", "A", "H", "HP", "HT", "R", "RP", "RT", "RD", "RE", "ED", "EE", "E",
    "FT", "FV", "F", "V", "O", "DS", "DR", "DF",
})

_TOKEN = re.compile(r"([A-Za-z]{1,3})(-?\d+)?")
_ECHO = re.compile(r"([A-Za-z]{1,3}-?\d*)\s*([*!].*)?")
_LIMIT = re.compile(r"!([PT])(?=[!*]|$)")


class ReplyKind(enum.Enum):
    """What one line from the unit is."""

    OK = "ok"            # '*' [value]
    ERROR = "error"      # '!' message
    LIMIT = "limit"      # unsolicited '!P' / '!T' (text: 'P' or 'T')
    BANNER = "banner"    # power-up / reset banner line
    ECHO = "echo"        # the echo of a command (text: the command, e.g. 'PP')
    GARBAGE = "garbage"  # anything else (text: repr of the bytes)


@dataclass(frozen=True)
class Reply:
    """One classified item of the unit's output; ``text`` depends on ``kind``."""

    kind: ReplyKind
    text: str = ""


@dataclass(frozen=True)
class Command:
    """One command token received by the unit.

    ``op`` is the upper-case command (``"PP"``), ``arg`` its integer argument or None,
    ``raw`` the token as received (what an echo repeats). ``op`` is empty for a token
    that is not letters plus an optional integer.
    """

    op: str
    arg: int | None
    raw: str

    @property
    def known(self) -> bool:
        return self.op in KNOWN_OPS


class PtuProtocolError(ValueError):
    """A reply that does not carry what the command asked for (e.g. verbose text)."""


# ------------------------------------------------------------------ driver side


def encode_command(op: str, arg: int | None = None) -> bytes:
    """``encode_command("PP", -500) == b"PP-500 "``; ``op`` must be a known command."""
    op_u = op.upper()
    if op_u not in KNOWN_OPS:
        raise ValueError(f"unknown PTU command {op!r}")
    if arg is None:
        return f"{op_u} ".encode("ascii")
    return f"{op_u}{int(arg)} ".encode("ascii")


def parse_int(reply: Reply) -> int:
    """The integer value of a terse ``* <n>`` reply; PtuProtocolError otherwise."""
    if reply.kind is not ReplyKind.OK:
        raise PtuProtocolError(f"expected '* <integer>', got {reply.kind.value} {reply.text!r}")
    try:
        return int(reply.text)
    except ValueError:
        raise PtuProtocolError(f"expected '* <integer>', got '* {reply.text}'") from None


def parse_float(reply: Reply) -> float:
    """The numeric value of a terse ``* <x>`` reply (e.g. a resolution in arcsec/step)."""
    if reply.kind is not ReplyKind.OK:
        raise PtuProtocolError(f"expected '* <number>', got {reply.kind.value} {reply.text!r}")
    try:
        value = float(reply.text)
    except ValueError:
        raise PtuProtocolError(f"expected '* <number>', got '* {reply.text}'") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise PtuProtocolError(f"expected a finite number, got '* {reply.text}'")
    return value


def classify_line(line: bytes) -> list[Reply]:
    """Classify one line of the unit's output (without its terminator)."""
    if any(b > 0x7E or (b < 0x20 and b != 0x09) for b in line):
        return [Reply(ReplyKind.GARBAGE, repr(line[:40]))]
    text = line.decode("ascii").strip()
    out: list[Reply] = []
    while (m := _LIMIT.match(text)) is not None:
        out.append(Reply(ReplyKind.LIMIT, m.group(1)))
        text = text[2:]
    if not text:
        return out
    if text[0] == "*":
        out.append(Reply(ReplyKind.OK, text[1:].strip()))
    elif text[0] == "!":
        out.append(Reply(ReplyKind.ERROR, text[1:].strip()))
    elif text[0] == "#" or text.lower().startswith("initializing"):
        out.append(Reply(ReplyKind.BANNER, text))
    elif (m := _ECHO.fullmatch(text)) is not None and _op_of(m.group(1)) in KNOWN_OPS:
        out.append(Reply(ReplyKind.ECHO, m.group(1).upper()))
        if m.group(2):
            out.extend(classify_line(m.group(2).encode("ascii")))
    else:
        out.append(Reply(ReplyKind.GARBAGE, repr(line[:40])))
    return out


def _op_of(token: str) -> str:
    m = _TOKEN.fullmatch(token)
    return m.group(1).upper() if m else ""


class ReplyParser:
    """Incremental line splitter + classifier for the unit's output.

    ``feed`` returns the items of every line completed so far; the result does not
    depend on how the bytes were split into chunks.
    """

    def __init__(self) -> None:
        self._buf = bytearray()

    def reset(self) -> None:
        """Forget a partial line (after a timeout, before resynchronising)."""
        self._buf.clear()

    @property
    def pending(self) -> int:
        """Bytes of an unfinished line held back."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Reply]:
        self._buf.extend(data)
        out: list[Reply] = []
        while True:
            end = _first_terminator(self._buf)
            if end is not None and end <= MAX_LINE:
                line = bytes(self._buf[:end])
                del self._buf[: end + 1]
                if line.strip(b" \t"):
                    out.extend(classify_line(line))
            elif len(self._buf) > MAX_LINE:
                out.append(Reply(ReplyKind.GARBAGE, repr(bytes(self._buf[:40]))))
                del self._buf[:MAX_LINE]
            else:
                return out


def _first_terminator(buf: bytearray) -> int | None:
    cr, lf = buf.find(b"\r"), buf.find(b"\n")
    if cr < 0:
        return lf if lf >= 0 else None
    return cr if lf < 0 else min(cr, lf)


# ------------------------------------------------------------------ unit side


def format_reply(reply: Reply, echo: str | None = None) -> bytes:
    """Bytes the unit sends for ``reply`` (CR LF ended), after the echo if given."""
    if reply.kind is ReplyKind.OK:
        body = f"* {reply.text}" if reply.text else "*"
    elif reply.kind is ReplyKind.ERROR:
        body = f"! {reply.text}"
    elif reply.kind is ReplyKind.LIMIT:
        body = f"!{reply.text}"
    elif reply.kind is ReplyKind.BANNER:
        body = reply.text
    else:
        raise ValueError(f"the unit does not send {reply.kind.value} replies")
    if echo is not None:
        body = f"{echo} {body}"
    return body.encode("ascii") + LINE_END


class CommandParser:
    """Incremental tokenizer of what the host sends: tokens end with space, CR or LF."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[Command]:
        self._buf.extend(data)
        out: list[Command] = []
        while True:
            end = _first_delimiter(self._buf)
            if end is not None and end <= MAX_TOKEN:
                token = bytes(self._buf[:end])
                del self._buf[: end + 1]
                if token:
                    out.append(parse_token(token))
            elif len(self._buf) > MAX_TOKEN:
                out.append(Command("", None, self._buf[:MAX_TOKEN].decode("latin-1")))
                del self._buf[:MAX_TOKEN]
            else:
                return out


def _first_delimiter(buf: bytearray) -> int | None:
    found = [i for i in (buf.find(b" "), buf.find(b"\r"), buf.find(b"\n")) if i >= 0]
    return min(found) if found else None


def parse_token(token: bytes) -> Command:
    """``b"pp-500"`` -> ``Command("PP", -500, "pp-500")``; op empty when malformed."""
    raw = token.decode("latin-1")
    m = _TOKEN.fullmatch(raw) if token.isascii() else None
    if m is None:
        return Command("", None, raw)
    arg = int(m.group(2)) if m.group(2) is not None else None
    return Command(m.group(1).upper(), arg, raw)
