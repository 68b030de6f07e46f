"""Vehicle speed and yaw rate from CAN frames: a pure decoder over any vehicle's DBC.

The vehicle is described only by a DBC file and two ``MESSAGE.SIGNAL`` names with
their units (and the yaw rate's sign), so the same code reads the simulated vehicle
(``config/vehicle.dbc``) or a production car's DBC (e.g. from opendbc). Output is SI
in the spec's convention: speed m/s forward, yaw rate rad/s counter-clockwise.

Configuration problems raise :class:`VehicleCanConfigError` (malformed DBC, unknown
message or signal), naming the DBC file and the signal; the appliance turns them
into exit status 2. Wire problems raise :class:`FrameDecodeError`, which the reader
counts by its ``reason``.
"""

from __future__ import annotations

import difflib
import enum
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cantools
from cantools.database.can import Database, Message
from cantools.database.errors import Error as CantoolsError
from cantools.database.errors import UnsupportedDatabaseFormatError

SPEED_UNITS = {"m/s": 1.0, "km/h": 1.0 / 3.6}
YAW_RATE_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}


class SignalKind(enum.Enum):
    SPEED = "speed"          # m/s, forward positive
    YAW_RATE = "yaw_rate"    # rad/s, counter-clockwise (left turn) positive


@dataclass(frozen=True)
class VehicleSignal:
    """One decoded value: ``t`` s (monotonic, or the recording clock in replay)."""

    t: float
    kind: SignalKind
    value: float


class VehicleCanConfigError(ValueError):
    """A bad DBC or signal name in the configuration (message names the file)."""

    def __init__(self, dbc: str | Path, what: str, problem: str) -> None:
        self.dbc = str(dbc)
        self.what = what
        self.problem = problem
        super().__init__(f"{self.dbc}: {what}: {problem}" if what else f"{self.dbc}: {problem}")


class FrameDecodeError(Exception):
    """A frame of a configured id that cannot be decoded.

    ``reason`` is ``"wrong_length"`` or ``"undecodable"``; ``"unknown_id"`` for a
    frame the configuration does not ask for.
    """

    def __init__(self, reason: str, detail: str) -> None:
        self.reason = reason
        super().__init__(detail)


@dataclass(frozen=True)
class SignalSpec:
    """Where one wanted value lives and how it becomes SI: ``value = factor * decoded``."""

    kind: SignalKind
    message: str
    signal: str
    frame_id: int
    is_extended: bool
    factor: float


def load_dbc(path: str | Path) -> Database:
    """Load a DBC; anything cantools cannot read -> VehicleCanConfigError naming the file.

    Loaded with ``strict=False`` because production DBCs often have overlapping
    signals that strict loading refuses (reference notes, section 1).
    """
    p = Path(path)
    if not p.is_file():
        raise VehicleCanConfigError(p, "", "DBC file not found")
    try:
        db = cantools.database.load_file(str(p), database_format="dbc", strict=False)
    except (UnsupportedDatabaseFormatError, CantoolsError,
            UnicodeDecodeError, ValueError, KeyError, IndexError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise VehicleCanConfigError(p, "", f"malformed DBC: {reason[:300]}") from None
    if not isinstance(db, Database):
        raise VehicleCanConfigError(p, "", "not a CAN database")
    return db


def resolve_signal(db: Database, dbc: str | Path, name: str, kind: SignalKind,
                   factor: float) -> SignalSpec:
    """``"MESSAGE.SIGNAL"`` -> SignalSpec; unknown names raise with close matches."""
    msg_name, dot, sig_name = name.partition(".")
    if not dot or not msg_name or not sig_name:
        raise VehicleCanConfigError(dbc, name, "expected MESSAGE.SIGNAL")
    messages = {m.name: m for m in db.messages}
    if msg_name not in messages:
        raise VehicleCanConfigError(dbc, name, f"no message {msg_name!r} in the DBC"
                                    + _did_you_mean(msg_name, list(messages)))
    message: Message = messages[msg_name]
    signals = [s.name for s in message.signals]
    if sig_name not in signals:
        raise VehicleCanConfigError(dbc, name, f"message {msg_name} has no signal {sig_name!r}"
                                    + _did_you_mean(sig_name, signals))
    return SignalSpec(kind, msg_name, sig_name, message.frame_id, message.is_extended_frame,
                      factor)


def _did_you_mean(name: str, options: list[str]) -> str:
    close = difflib.get_close_matches(name, options, n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


class VehicleSignalDecoder:
    """Frames -> :class:`VehicleSignal` values. Pure: no bus, no clock.

    :param dbc: path of the vehicle's DBC.
    :param speed: ``MESSAGE.SIGNAL`` of the speed; ``speed_unit`` "m/s" or "km/h".
    :param yaw_rate: ``MESSAGE.SIGNAL`` of the yaw rate; ``yaw_rate_unit`` "rad/s" or
        "deg/s"; ``yaw_rate_sign`` -1 when the vehicle reports clockwise positive.
    """

    def __init__(self, dbc: str | Path, *, speed: str, speed_unit: str, yaw_rate: str,
                 yaw_rate_unit: str, yaw_rate_sign: int = 1) -> None:
        if speed_unit not in SPEED_UNITS:
            raise VehicleCanConfigError(dbc, speed, f"speed unit {speed_unit!r} is not m/s or km/h")
        if yaw_rate_unit not in YAW_RATE_UNITS:
            raise VehicleCanConfigError(dbc, yaw_rate,
                                        f"yaw rate unit {yaw_rate_unit!r} is not rad/s or deg/s")
        if yaw_rate_sign not in (1, -1):
            raise VehicleCanConfigError(dbc, yaw_rate,
                                        f"yaw rate sign {yaw_rate_sign} is not 1 or -1")
        self.dbc = str(dbc)
        self._db = load_dbc(dbc)
        self.specs = (
            resolve_signal(self._db, dbc, speed, SignalKind.SPEED, SPEED_UNITS[speed_unit]),
            resolve_signal(self._db, dbc, yaw_rate, SignalKind.YAW_RATE,
                           yaw_rate_sign * YAW_RATE_UNITS[yaw_rate_unit]),
        )
        self._by_id: dict[tuple[int, bool], tuple[Message, list[SignalSpec]]] = {}
        for spec in self.specs:
            key = (spec.frame_id, spec.is_extended)
            message = self._db.get_message_by_name(spec.message)
            self._by_id.setdefault(key, (message, []))[1].append(spec)

    @property
    def database(self) -> Database:
        """The loaded DBC (e.g. to encode test frames for the same vehicle)."""
        return self._db

    @property
    def frame_ids(self) -> list[tuple[int, bool]]:
        """(arbitration id, is extended) of every frame the decoder needs."""
        return list(self._by_id)

    def can_filters(self) -> list[dict[str, int | bool]]:
        """python-can receive filters that pass exactly the needed frames."""
        return [{"can_id": fid, "can_mask": 0x1FFFFFFF if ext else 0x7FF, "extended": ext}
                for fid, ext in self._by_id]

    def wants(self, arbitration_id: int, is_extended: bool) -> bool:
        return (arbitration_id, is_extended) in self._by_id

    def decode(self, arbitration_id: int, data: bytes | bytearray, t: float,
               is_extended: bool = False) -> list[VehicleSignal]:
        """The wanted values carried by one frame, in SI units, stamped ``t``."""
        entry = self._by_id.get((arbitration_id, is_extended))
        if entry is None:
            raise FrameDecodeError("unknown_id", f"frame 0x{arbitration_id:X} is not configured")
        message, specs = entry
        if len(data) != message.length:
            raise FrameDecodeError("wrong_length", f"{message.name} (0x{arbitration_id:X}): "
                                   f"{len(data)} bytes, the DBC says {message.length}")
        try:
            values = message.decode(bytes(data), decode_choices=False, scaling=True)
        except (CantoolsError, ValueError, KeyError, IndexError) as exc:
            raise FrameDecodeError("undecodable", f"{message.name}: {exc}") from None
        if not isinstance(values, dict):
            raise FrameDecodeError("undecodable", f"{message.name}: container message")
        out = []
        for spec in specs:
            raw = values.get(spec.signal)
            if not isinstance(raw, (int, float)):
                raise FrameDecodeError("undecodable", f"{spec.message}.{spec.signal} absent "
                                       "(multiplexed out) or not numeric")
            out.append(VehicleSignal(t, spec.kind, spec.factor * float(raw)))
        return out


class VehicleSignalEncoder:
    """SI speed and yaw rate -> the frames that carry them: the inverse of a decoder.

    Encodes through the same DBC and signal names as ``decoder`` (so any vehicle's DBC
    works), with cantools. The other signals of those messages hold their DBC initial value
    (0 where the DBC gives none, moved into the signal's range). Used to give footage
    without a vehicle bus (a dashcam video) the CAN frames the appliance decodes. Pure.
    """

    def __init__(self, decoder: VehicleSignalDecoder) -> None:
        db = decoder.database
        self.messages: list[tuple[Message, list[SignalSpec]]] = []
        for spec in decoder.specs:
            message = db.get_message_by_name(spec.message)
            for m, specs in self.messages:
                if m is message:
                    specs.append(spec)
                    break
            else:
                self.messages.append((message, [spec]))

    def check(self, kind: SignalKind, value: float) -> None:
        """Raise ValueError, naming the signal, when ``value`` (SI) is outside its DBC range."""
        for message, specs in self.messages:
            for spec in specs:
                if spec.kind is kind:
                    _raw_in_range(message, spec, value)

    def encode(self, speed_m_s: float, yaw_rate_rad_s: float
               ) -> list[tuple[int, bool, bytes]]:
        """(arbitration id, is extended, data) of every message carrying the two values."""
        si = {SignalKind.SPEED: speed_m_s, SignalKind.YAW_RATE: yaw_rate_rad_s}
        out = []
        for message, specs in self.messages:
            values: dict[str, float] = {s.name: _resting(s) for s in message.signals}
            for spec in specs:
                values[spec.signal] = _raw_in_range(message, spec, si[spec.kind])
            try:
                data = message.encode(values, scaling=True, strict=True)
            except (CantoolsError, ValueError, KeyError) as exc:
                raise ValueError(f"{message.name}: cannot encode {values}: {exc}") from None
            out.append((message.frame_id, message.is_extended_frame, bytes(data)))
        return out


def _resting(signal: Any) -> float:
    """A signal's value when nothing sets it: its initial value, else 0, within its range."""
    v = float(signal.initial) if isinstance(signal.initial, (int, float)) else 0.0
    if signal.minimum is not None and v < signal.minimum:
        v = float(signal.minimum)
    if signal.maximum is not None and v > signal.maximum:
        v = float(signal.maximum)
    return v


def _raw_in_range(message: Message, spec: SignalSpec, value: float) -> float:
    """``value`` (SI) in the signal's own unit and sign; ValueError when out of its range."""
    sig = message.get_signal_by_name(spec.signal)
    v = value / spec.factor
    lo, hi = sig.minimum, sig.maximum
    if not math.isfinite(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
        unit = f" {sig.unit}" if sig.unit else ""
        raise ValueError(f"{spec.message}.{spec.signal}: {v:g}{unit} is outside the DBC's "
                         f"range [{lo}, {hi}]")
    return v
