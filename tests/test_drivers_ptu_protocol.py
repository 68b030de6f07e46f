"""PTU-D46 protocol bytes <-> messages, and the simulated unit's model (no ports)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.ptu_protocol import (
    MAX_LINE,
    Command,
    CommandParser,
    PtuProtocolError,
    Reply,
    ReplyKind,
    ReplyParser,
    classify_line,
    encode_command,
    format_reply,
    parse_float,
    parse_int,
    parse_token,
)
from drivers.ptu_unit import ACCEL, PAN_LIMITS, SPEED_BOUNDS, UnitModel, advance

OK, ERROR, LIMIT, BANNER, ECHO, GARBAGE = (ReplyKind.OK, ReplyKind.ERROR, ReplyKind.LIMIT,
                                           ReplyKind.BANNER, ReplyKind.ECHO, ReplyKind.GARBAGE)


def test_encode_command() -> None:
    assert encode_command("PP") == b"PP "
    assert encode_command("pp", -500) == b"PP-500 "
    assert encode_command("PS", 1000) == b"PS1000 "
    with pytest.raises(ValueError, match="unknown PTU command"):
        encode_command("ZZ")


@pytest.mark.parametrize("line, expected", [
    (b"* 100", [Reply(OK, "100")]),
    (b"*", [Reply(OK, "")]),
    (b"* 185.1428", [Reply(OK, "185.1428")]),
    (b"! Maximum allowable Pan position is 3090",
     [Reply(ERROR, "Maximum allowable Pan position is 3090")]),
    (b"!P", [Reply(LIMIT, "P")]),
    (b"!T!T!P!P*", [Reply(LIMIT, "T"), Reply(LIMIT, "T"), Reply(LIMIT, "P"), Reply(LIMIT, "P"),
                    Reply(OK, "")]),
    (b"!P* -12", [Reply(LIMIT, "P"), Reply(OK, "-12")]),
    (b"! Pan speed cannot exceed 2902 positions/sec",
     [Reply(ERROR, "Pan speed cannot exceed 2902 positions/sec")]),
    (b"PP * 100", [Reply(ECHO, "PP"), Reply(OK, "100")]),
    (b"pp1000 *", [Reply(ECHO, "PP1000"), Reply(OK, "")]),
    (b"TO100", [Reply(ECHO, "TO100")]),
    (b"PP * Current Pan position is 0",
     [Reply(ECHO, "PP"), Reply(OK, "Current Pan position is 0")]),
    (b"### PAN-TILT CONTROLLER", [Reply(BANNER, "### PAN-TILT CONTROLLER")]),
    (b"Initializing...", [Reply(BANNER, "Initializing...")]),
    (b"\xff\xfe* 100", [Reply(GARBAGE, repr(b"\xff\xfe* 100"))]),
    (b"hello * 1", [Reply(GARBAGE, repr(b"hello * 1"))]),
    (b"ZZ * 1", [Reply(GARBAGE, repr(b"ZZ * 1"))]),
])
def test_classify_line(line: bytes, expected: list[Reply]) -> None:
    assert classify_line(line) == expected


def test_parser_line_ends_partial_lines_and_empty_lines() -> None:
    p = ReplyParser()
    assert p.feed(b"* 1") == []
    assert p.pending == 3
    assert p.feed(b"2\r") == [Reply(OK, "12")]
    # CR LF, bare LF, and the empty line between echo and reply (TO100\r\n*\r\n) are skipped
    assert p.feed(b"\n* 3\n\r\nTO100\r\n*\r\n") == [Reply(OK, "3"), Reply(ECHO, "TO100"),
                                                   Reply(OK, "")]
    assert p.pending == 0


def test_parser_cuts_an_endless_line_as_garbage() -> None:
    p = ReplyParser()
    out = p.feed(b"x" * (MAX_LINE + 10))
    assert [r.kind for r in out] == [GARBAGE]
    assert p.pending == 10
    assert p.feed(b"\r\n* 5\r\n") == [Reply(GARBAGE, repr(b"x" * 10)), Reply(OK, "5")]


def test_parse_values() -> None:
    assert parse_int(Reply(OK, "-907")) == -907
    assert parse_float(Reply(OK, "185.1428")) == pytest.approx(185.1428)
    with pytest.raises(PtuProtocolError, match="Current Pan position"):
        parse_int(Reply(OK, "Current Pan position is 0"))
    with pytest.raises(PtuProtocolError):
        parse_int(Reply(ERROR, "Axis Error"))
    with pytest.raises(PtuProtocolError):
        parse_float(Reply(OK, "nan"))


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=700), cuts=st.lists(st.integers(0, 700), max_size=8))
def test_parser_on_arbitrary_bytes_never_raises_and_ignores_chunking(
        data: bytes, cuts: list[int]) -> None:
    whole = ReplyParser().feed(data)
    p = ReplyParser()
    chunked: list[Reply] = []
    bounds = [0, *sorted(c for c in cuts if c <= len(data)), len(data)]
    for a, b in zip(bounds, bounds[1:]):
        chunked.extend(p.feed(data[a:b]))
    assert chunked == whole
    assert all(isinstance(r, Reply) and isinstance(r.kind, ReplyKind) for r in whole)
    assert p.pending <= MAX_LINE
    for r in whole:   # whatever parses as OK carries only printable ASCII
        assert r.text.isprintable()


@settings(max_examples=200, deadline=None)
@given(value=st.integers(-100000, 100000), echo=st.sampled_from([None, "PP", "tp"]),
       noise=st.binary(max_size=30).map(lambda b: bytes(x | 0x80 for x in b)))
def test_reply_round_trip_survives_a_garbage_line(value: int, echo: str | None,
                                                  noise: bytes) -> None:
    wire = (noise + b"\r\n" if noise else b"") + format_reply(Reply(OK, str(value)), echo=echo)
    replies = [r for r in ReplyParser().feed(wire) if r.kind is OK]
    assert len(replies) == 1 and parse_int(replies[0]) == value


def test_command_parser_tokens() -> None:
    p = CommandParser()
    assert p.feed(b"PP TP-907\rps1000\nE") == [
        Command("PP", None, "PP"), Command("TP", -907, "TP-907"), Command("PS", 1000, "ps1000")]
    assert p.feed(b"D ") == [Command("ED", None, "ED")]
    assert parse_token(b"P!1") == Command("", None, "P!1")
    assert not parse_token(b"XYZ").known


@settings(max_examples=200, deadline=None)
@given(data=st.binary(max_size=200), cut=st.integers(0, 200))
def test_command_parser_on_arbitrary_bytes(data: bytes, cut: int) -> None:
    whole = CommandParser().feed(data)
    p = CommandParser()
    assert p.feed(data[:cut]) + p.feed(data[cut:]) == whole


# ------------------------------------------------------------------ simulated unit


def test_advance_respects_speed_and_acceleration_and_stops_on_target() -> None:
    pos, vel, vmax, accel, h = 0.0, 0.0, 1000.0, 2000.0, 0.01
    trace = [(pos, vel)]
    for _ in range(400):
        pos, vel = advance(pos, vel, 3000.0, vmax, accel, h)
        trace.append((pos, vel))
    assert trace[-1] == (3000.0, 0.0)
    vels = [v for _, v in trace]
    assert max(vels) <= vmax + 1e-9
    assert max(abs(b - a) for a, b in zip(vels, vels[1:])) <= accel * h + 1e-6
    assert all(p <= 3000.0 for p, _ in trace)          # no overshoot
    # time-optimal trapezoid: d / v + v / a = 3.5 s
    arrival = next(i for i, (p, v) in enumerate(trace) if p == 3000.0) * h
    assert arrival == pytest.approx(3.5, abs=0.06)


def test_advance_reverses_a_move_changed_on_the_fly() -> None:
    pos, vel = advance(0.0, 0.0, 3000.0, 1000.0, 2000.0, 1.0)
    assert vel == pytest.approx(1000.0)
    pos, vel = advance(pos, vel, -100.0, 1000.0, 2000.0, 3.0)
    assert (pos, vel) == (-100.0, 0.0)


def test_unit_factory_state_limits_and_speed_bounds() -> None:
    u = UnitModel()
    assert u.execute("PP", 0.0).data == b"PP * Current Pan position is 0\r\n"   # echo + verbose
    assert u.execute("ED", 0.0).data == b"ED *\r\n"      # echoed while it is received
    assert u.execute("FT", 0.0).data == b"*\r\n"
    assert u.execute("PX", 0.0).data == f"* {PAN_LIMITS[1]}\r\n".encode()
    assert u.execute(f"PP{PAN_LIMITS[1] + 1}", 0.0).data == \
        f"! Maximum allowable Pan position is {PAN_LIMITS[1]}\r\n".encode()
    assert u.execute("PS5000", 0.0).data.startswith(b"! Pan speed cannot exceed")
    assert u.execute(f"PS{SPEED_BOUNDS[0] - 1}", 0.0).data.startswith(b"! Motor speed")
    assert u.execute("QQ", 0.0).data == b"! Illegal command\r\n"
    assert u.execute("PS1000", 0.0).data == b"*\r\n"
    assert u.execute("PP1000", 0.0).data == b"*\r\n"
    assert u.execute("PP", 0.5).data == f"* {round(0.5 * 0.5 * ACCEL * 0.5)}\r\n".encode()
    assert u.execute("PP", 10.0).data == b"* 1000\r\n"
    answer = u.execute("R", 10.0)
    assert answer.data == b"!T!T!P!P*\r\n" and answer.delay_s > 0.0
    assert u.execute("TP", 11.0).data == b"* 0\r\n"


def test_unit_await_reports_the_motion_time() -> None:
    u = UnitModel()
    u.execute("S", 0.0)   # slaved: moves wait for A
    u.execute("PP2000", 0.0)
    assert u.execute("PP", 1.0).data.endswith(b"is 0\r\n")
    answer = u.execute("A", 1.0)
    assert answer.delay_s == pytest.approx(2000 / 1000 + 1000 / 2000, abs=0.06)
    pan, _ = u.position(1.0 + answer.delay_s)
    assert math.isclose(pan, 2000.0)
