"""The appliance's CAN messages to the HMI: encode/decode with cantools, counter and CRC.

``config/appliance.dbc`` defines ``CollisionWarning`` and ``ApplianceStatus``
(little-endian; a 4-bit rolling ``Counter``; ``Crc`` = CRC-8 SAE J1850 over bytes 0-6,
in byte 7). Identifiers come from the configuration. Pure: no bus, no clock.

Values outside a signal's range are clamped; unknown quantities use the DBC's
"unknown" raw values: time to collision 0x3FF, distance 0xFFF. The bearing has no
unknown value in the DBC: an unknown bearing is sent as 0.0 deg (straight ahead).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import can
import cantools
from cantools.database.can import Database, Message
from cantools.database.errors import Error as CantoolsError
from cantools.database.errors import UnsupportedDatabaseFormatError
from crccheck.crc import Crc8SaeJ1850

WARNING_NAME = "CollisionWarning"
STATUS_NAME = "ApplianceStatus"
TTC_UNKNOWN_RAW = 0x3FF
DISTANCE_UNKNOWN_RAW = 0xFFF


def crc8_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 (poly 0x1D, init 0xFF, xor-out 0xFF); 0x4B for b"123456789"."""
    return int(Crc8SaeJ1850.calc(data))


@dataclass(frozen=True)
class HmiWarning:
    """What ``CollisionWarning`` carries. level 0 cleared, 1 caution, 2 warning.

    ttc_s: s; distance_m: m from the front bumper; bearing_rad: vehicle frame, left +.
    None = unknown.
    """

    level: int = 0
    track_id: int = 0
    ttc_s: float | None = None
    distance_m: float | None = None
    bearing_rad: float | None = None


@dataclass(frozen=True)
class HmiStatus:
    """What ``ApplianceStatus`` carries. state 0 starting, 1 ok, 2 degraded, 3 fault."""

    state: int = 0
    fault_camera: bool = False
    fault_vehicle_can_stale: bool = False
    fault_ptu: bool = False
    fault_overrun: bool = False
    frame_rate_hz: float = 0.0
    latency_ms: float = 0.0


@dataclass(frozen=True)
class Decoded:
    """A received HMI frame: the payload, its counter and whether its CRC matched."""

    payload: HmiWarning | HmiStatus
    counter: int
    crc_ok: bool


class HmiDbcError(ValueError):
    """The appliance DBC cannot be used (names the file and what is wrong)."""


class HmiCodec:
    """Encoder/decoder of the two HMI messages.

    :param dbc: path of the appliance DBC.
    :param warning_id, status_id: CAN ids (11 bit) to send them with.
    :param channel: channel name put on the messages (shows in ``can_out.log``).
    """

    def __init__(self, dbc: str | Path, warning_id: int = 0x4C0, status_id: int = 0x4C1,
                 channel: str | None = None) -> None:
        try:
            db = cantools.database.load_file(str(dbc), database_format="dbc")
        except (OSError, UnsupportedDatabaseFormatError, CantoolsError, UnicodeDecodeError,
                ValueError) as exc:
            reason = " ".join(str(exc).split())[:300]
            raise HmiDbcError(f"{dbc}: cannot load DBC: {reason}") from None
        if not isinstance(db, Database):
            raise HmiDbcError(f"{dbc}: not a CAN database")
        self.warning_msg = _message(db, dbc, WARNING_NAME)
        self.status_msg = _message(db, dbc, STATUS_NAME)
        for wid in (warning_id, status_id):
            if not 0 <= wid <= 0x7FF:
                raise HmiDbcError(f"CAN id 0x{wid:X} is not an 11-bit id")
        self.warning_id = warning_id
        self.status_id = status_id
        self.channel = channel

    # ---------------------------------------------------------------- encode

    def encode_warning(self, w: HmiWarning, counter: int) -> bytes:
        level = min(2, max(0, int(w.level)))
        ttc = None if w.ttc_s is None or not math.isfinite(w.ttc_s) or w.ttc_s < 0 else w.ttc_s
        dist = None if w.distance_m is None or not math.isfinite(w.distance_m) else w.distance_m
        bearing_deg = 0.0 if w.bearing_rad is None or not math.isfinite(w.bearing_rad) else \
            (math.degrees(w.bearing_rad) + 180.0) % 360.0 - 180.0
        values = {
            "Level": level,
            "TrackId": int(w.track_id) % 256 if level > 0 else 0,
            "TimeToCollision": TTC_UNKNOWN_RAW * 0.01 if ttc is None else
            min(round(ttc, 2), (TTC_UNKNOWN_RAW - 1) * 0.01),
            "Distance": DISTANCE_UNKNOWN_RAW * 0.1 if dist is None else
            min(max(round(dist, 1), 0.0), (DISTANCE_UNKNOWN_RAW - 1) * 0.1),
            "Bearing": round(bearing_deg, 1),
        }
        return self._seal(self.warning_msg, values, counter)

    def encode_status(self, s: HmiStatus, counter: int) -> bytes:
        values = {
            "State": min(3, max(0, int(s.state))),
            "FaultCamera": int(bool(s.fault_camera)),
            "FaultVehicleCanStale": int(bool(s.fault_vehicle_can_stale)),
            "FaultPtu": int(bool(s.fault_ptu)),
            "FaultOverrun": int(bool(s.fault_overrun)),
            "FrameRate": _clamp(s.frame_rate_hz, 0.0, 102.3, 1),
            "Latency": _clamp(s.latency_ms, 0.0, 409.5, 1),
        }
        return self._seal(self.status_msg, values, counter)

    def _seal(self, message: Message, values: dict[str, float], counter: int) -> bytes:
        """Encode with the counter, then put the CRC of bytes 0-6 in byte 7."""
        data = bytearray(message.encode({**values, "Counter": counter % 16, "Crc": 0},
                                        scaling=True, strict=True))
        data[7] = crc8_j1850(bytes(data[:7]))
        return bytes(data)

    def warning_message(self, w: HmiWarning, counter: int, t: float) -> can.Message:
        return self._frame(self.warning_id, self.encode_warning(w, counter), t)

    def status_message(self, s: HmiStatus, counter: int, t: float) -> can.Message:
        return self._frame(self.status_id, self.encode_status(s, counter), t)

    def _frame(self, arbitration_id: int, data: bytes, t: float) -> can.Message:
        return can.Message(timestamp=t, arbitration_id=arbitration_id, is_extended_id=False,
                           data=data, channel=self.channel, is_rx=False)

    # ---------------------------------------------------------------- decode (HMI side)

    def decode(self, arbitration_id: int, data: bytes | bytearray) -> Decoded:
        """Decode a frame of either id (what an HMI does); KeyError for other ids."""
        if arbitration_id == self.warning_id:
            message = self.warning_msg
        elif arbitration_id == self.status_id:
            message = self.status_msg
        else:
            raise KeyError(f"0x{arbitration_id:X} is not an HMI frame")
        raw = _signals(message.decode(bytes(data), decode_choices=False, scaling=False))
        v = _signals(message.decode(bytes(data), decode_choices=False, scaling=True))
        crc_ok = len(data) == 8 and crc8_j1850(bytes(data[:7])) == data[7]
        payload: HmiWarning | HmiStatus
        if message is self.warning_msg:
            payload = HmiWarning(
                level=int(v["Level"]), track_id=int(v["TrackId"]),
                ttc_s=None if raw["TimeToCollision"] == TTC_UNKNOWN_RAW
                else float(v["TimeToCollision"]),
                distance_m=None if raw["Distance"] == DISTANCE_UNKNOWN_RAW
                else float(v["Distance"]),
                bearing_rad=math.radians(float(v["Bearing"])))
        else:
            payload = HmiStatus(
                state=int(v["State"]), fault_camera=bool(v["FaultCamera"]),
                fault_vehicle_can_stale=bool(v["FaultVehicleCanStale"]),
                fault_ptu=bool(v["FaultPtu"]), fault_overrun=bool(v["FaultOverrun"]),
                frame_rate_hz=float(v["FrameRate"]), latency_ms=float(v["Latency"]))
        return Decoded(payload, int(raw["Counter"]), crc_ok)


def _signals(decoded: object) -> dict[str, float]:
    """The numeric signal values of a decoded (non-container) message."""
    if not isinstance(decoded, dict):
        raise TypeError("HMI messages are not container messages")
    return {k: float(x) for k, x in decoded.items() if isinstance(x, (int, float))}


def _clamp(x: float, lo: float, hi: float, digits: int) -> float:
    if not math.isfinite(x):
        return lo
    return min(hi, max(lo, round(x, digits)))


def _message(db: Database, dbc: str | Path, name: str) -> Message:
    try:
        message = db.get_message_by_name(name)
    except KeyError:
        raise HmiDbcError(f"{dbc}: no message {name}") from None
    names = {s.name: s for s in message.signals}
    crc = names.get("Crc")
    if "Counter" not in names or crc is None or message.length != 8 or crc.start != 56 \
            or crc.length != 8 or crc.byte_order != "little_endian":
        raise HmiDbcError(f"{dbc}: {name} needs 8 bytes, a Counter and an 8-bit Crc in byte 7")
    return message
