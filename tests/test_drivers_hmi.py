"""HMI messages: pack-then-parse with the appliance DBC, counter, CRC, and the pure scheduler."""

from __future__ import annotations

import math
from pathlib import Path

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.hmi_can import HmiScheduler
from drivers.hmi_codec import HmiCodec, HmiDbcError, HmiStatus, HmiWarning, crc8_j1850

CONFIG = Path(__file__).resolve().parents[1] / "config"
DBC = CONFIG / "appliance.dbc"


@pytest.fixture(scope="module")
def codec() -> HmiCodec:
    return HmiCodec(DBC, warning_id=0x4C0, status_id=0x4C1, channel="can0")


def test_crc8_sae_j1850_check_value() -> None:
    assert crc8_j1850(b"123456789") == 0x4B
    assert crc8_j1850(b"") == 0x00


def test_warning_unknowns_use_the_dbc_raw_values(codec: HmiCodec) -> None:
    data = codec.encode_warning(HmiWarning(level=1, track_id=7), counter=5)
    db = cantools.database.load_file(str(DBC))
    assert isinstance(db, cantools.database.can.Database)
    raw = db.get_message_by_name("CollisionWarning").decode(data, decode_choices=False,
                                                           scaling=False)
    assert isinstance(raw, dict)
    assert raw["TimeToCollision"] == 0x3FF and raw["Distance"] == 0xFFF
    assert raw["Bearing"] == 0 and raw["Counter"] == 5 and raw["Level"] == 1 and raw["TrackId"] == 7
    assert data[7] == crc8_j1850(data[:7])
    decoded = codec.decode(0x4C0, data)
    assert decoded.crc_ok and decoded.counter == 5
    assert decoded.payload == HmiWarning(level=1, track_id=7, ttc_s=None, distance_m=None,
                                         bearing_rad=0.0)


def test_warning_bearing_sign_wrap_and_clamping(codec: HmiCodec) -> None:
    def round_trip(w: HmiWarning) -> HmiWarning:
        payload = codec.decode(0x4C0, codec.encode_warning(w, 0)).payload
        assert isinstance(payload, HmiWarning)
        return payload

    left = round_trip(HmiWarning(2, 1, 1.5, 20.0, math.radians(10.0)))
    assert left.bearing_rad == pytest.approx(math.radians(10.0))          # left positive
    right = round_trip(HmiWarning(2, 1, 1.5, 20.0, math.radians(190.0)))
    assert right.bearing_rad == pytest.approx(math.radians(-170.0))       # wrapped
    far = round_trip(HmiWarning(2, 300, 99.0, 1e6, None))
    assert far.ttc_s == pytest.approx(10.22) and far.distance_m == pytest.approx(409.4)
    assert far.track_id == 300 % 256
    assert round_trip(HmiWarning(2, 1, -1.0, math.inf, 0.0)).ttc_s is None   # nonsense -> unknown
    assert round_trip(HmiWarning(0, 9, 1.0, 1.0, 0.0)).track_id == 0       # cleared: track 0


def test_crc_detects_corruption(codec: HmiCodec) -> None:
    data = bytearray(codec.encode_warning(HmiWarning(2, 3, 1.0, 5.0, 0.1), 9))
    assert codec.decode(0x4C0, bytes(data)).crc_ok
    for byte in range(8):
        corrupted = bytearray(data)
        corrupted[byte] ^= 0x10
        assert not codec.decode(0x4C0, bytes(corrupted)).crc_ok


@settings(max_examples=200, deadline=None)
@given(level=st.integers(0, 2), track=st.integers(0, 10_000),
       ttc=st.one_of(st.none(), st.floats(0.0, 10.2)),
       dist=st.one_of(st.none(), st.floats(0.0, 409.0)),
       bearing=st.floats(-math.pi + 0.01, math.pi - 0.01), counter=st.integers(0, 100))
def test_warning_pack_then_parse(codec: HmiCodec, level: int, track: int, ttc: float | None,
                                 dist: float | None, bearing: float, counter: int) -> None:
    decoded = codec.decode(0x4C0, codec.encode_warning(
        HmiWarning(level, track, ttc, dist, bearing), counter))
    w = decoded.payload
    assert isinstance(w, HmiWarning) and decoded.crc_ok and decoded.counter == counter % 16
    assert w.level == level and w.track_id == (track % 256 if level else 0)
    assert (w.ttc_s is None) == (ttc is None) and (w.distance_m is None) == (dist is None)
    if ttc is not None and w.ttc_s is not None:
        assert w.ttc_s == pytest.approx(ttc, abs=0.005 + 1e-9)
    if dist is not None and w.distance_m is not None:
        assert w.distance_m == pytest.approx(dist, abs=0.05 + 1e-9)
    assert w.bearing_rad == pytest.approx(bearing, abs=math.radians(0.05) + 1e-9)


@settings(max_examples=100, deadline=None)
@given(state=st.integers(0, 3), faults=st.tuples(*[st.booleans()] * 4),
       rate=st.floats(0.0, 102.0), latency=st.floats(0.0, 409.0), counter=st.integers(0, 15))
def test_status_pack_then_parse(codec: HmiCodec, state: int, faults: tuple[bool, ...],
                                rate: float, latency: float, counter: int) -> None:
    s = HmiStatus(state, fault_camera=faults[0], fault_vehicle_can_stale=faults[1],
                  fault_ptu=faults[2], fault_overrun=faults[3], frame_rate_hz=rate,
                  latency_ms=latency)
    decoded = codec.decode(0x4C1, codec.encode_status(s, counter))
    p = decoded.payload
    assert isinstance(p, HmiStatus) and decoded.crc_ok and decoded.counter == counter
    assert (p.state, p.fault_camera, p.fault_vehicle_can_stale, p.fault_ptu, p.fault_overrun) == \
        (state, *faults)
    assert p.frame_rate_hz == pytest.approx(rate, abs=0.05 + 1e-9)
    assert p.latency_ms == pytest.approx(latency, abs=0.05 + 1e-9)


def test_codec_refuses_a_dbc_without_the_hmi_messages() -> None:
    with pytest.raises(HmiDbcError, match=r"vehicle\.dbc: no message CollisionWarning"):
        HmiCodec(CONFIG / "vehicle.dbc")


def test_configured_ids_are_used(codec: HmiCodec) -> None:
    other = HmiCodec(DBC, warning_id=0x123, status_id=0x124)
    msg = other.warning_message(HmiWarning(1, 1), 0, 1.0)
    assert (msg.arbitration_id, msg.is_extended_id, msg.dlc) == (0x123, False, 8)
    assert other.status_message(HmiStatus(), 0, 1.0).arbitration_id == 0x124


# ------------------------------------------------------------------ scheduler


def run(scheduler: HmiScheduler, times: list[float], warnings: list[HmiWarning],
        status: HmiStatus = HmiStatus(state=1)) -> list[tuple[float, int, bytes]]:
    out = []
    for t, w in zip(times, warnings):
        frames = scheduler.update(t, w, status)
        out += [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in frames]
    return out


def test_status_heartbeat_every_period_on_a_fixed_grid(codec: HmiCodec) -> None:
    times = [k / 30.0 for k in range(90)]                 # 3 s of frames at 30 fps
    frames = run(HmiScheduler(codec, 0.1), times, [HmiWarning()] * len(times))
    status_t = [t for t, fid, _ in frames if fid == 0x4C1]
    assert all(fid == 0x4C1 for _, fid, _ in frames)      # level 0 throughout: no warnings
    assert len(status_t) == 30
    # the k-th heartbeat goes with the first frame at or after k * 100 ms: no drift
    for k, t in enumerate(status_t):
        assert k * 0.1 - 1e-9 <= t < k * 0.1 + 1 / 30.0 + 1e-9


def test_warning_on_change_and_repeated_while_active(codec: HmiCodec) -> None:
    s = HmiScheduler(codec, 0.1)
    seq = [(0.00, HmiWarning(0)), (0.05, HmiWarning(1, 4, 3.0)), (0.08, HmiWarning(1, 4, 2.9)),
           (0.14, HmiWarning(1, 4, 2.8)), (0.16, HmiWarning(2, 4, 1.9)),
           (0.20, HmiWarning(2, 5, 1.8)),
           (0.31, HmiWarning(2, 5, 1.7)), (0.33, HmiWarning(0)), (0.50, HmiWarning(0))]
    got = []
    for t, w in seq:
        for m in s.update(t, w, HmiStatus(1)):
            if m.arbitration_id == 0x4C0:
                d = codec.decode(m.arbitration_id, m.data)
                assert isinstance(d.payload, HmiWarning) and d.crc_ok
                ttc = None if d.payload.ttc_s is None else round(d.payload.ttc_s, 2)
                got.append((t, d.payload.level, d.payload.track_id, ttc, d.counter))
    assert got == [
        (0.05, 1, 4, 3.0, 0),    # level 0 -> 1: at once (level 0 at start sends nothing)
        (0.16, 2, 4, 1.9, 1),    # 0.08 and 0.14 are before the repeat (0.15); 1 -> 2 at once
        (0.20, 2, 5, 1.8, 2),    # new track: at once
        (0.31, 2, 5, 1.7, 3),    # repeat 100 ms after the last change, with the latest TTC
        (0.33, 0, 0, None, 4),   # cleared: once, then silence
    ]


def test_counters_roll_per_message_and_replay_is_deterministic(codec: HmiCodec) -> None:
    times = [k * 0.05 for k in range(80)]
    warnings = [HmiWarning(1 + (k // 10) % 2, 3, 2.0 - k * 0.01) for k in range(80)]
    a = run(HmiScheduler(codec, 0.1), times, warnings)
    b = run(HmiScheduler(codec, 0.1), times, warnings)
    assert a == b
    for fid in (0x4C0, 0x4C1):
        counters = [codec.decode(fid, d).counter for _, i, d in a if i == fid]
        assert len(counters) > 16
        assert counters == [k % 16 for k in range(len(counters))]


def test_after_a_gap_the_grid_restarts_instead_of_bursting(codec: HmiCodec) -> None:
    s = HmiScheduler(codec, 0.1)
    assert len(s.update(0.0, HmiWarning(), HmiStatus())) == 1
    assert len(s.update(5.0, HmiWarning(), HmiStatus())) == 1
    assert s.next_due() == pytest.approx(5.1)
    assert s.update(5.05, HmiWarning(), HmiStatus()) == []
