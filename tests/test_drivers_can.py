"""Vehicle CAN reader and HMI CAN writer over real python-can buses (virtual, udp_multicast,
SocketCAN where the kernel has it)."""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import cantools
import pytest

from drivers.handoff import Handoff
from drivers.hmi_can import HmiCanWriter
from drivers.hmi_codec import HmiCodec, HmiStatus, HmiWarning
from drivers.link import LinkState
from drivers.vehicle_can import (
    SignalKind,
    VehicleCanConfigError,
    VehicleCanReader,
    VehicleSignal,
    VehicleSignalDecoder,
)

CONFIG = Path(__file__).resolve().parents[1] / "config"
VEHICLE_DBC = CONFIG / "vehicle.dbc"
WAIT = 5.0
_channels = iter(range(1_000_000))


def channel_name() -> str:
    """A virtual channel of our own (virtual channels are process-wide)."""
    return f"cw-test-{os.getpid()}-{next(_channels)}"


@pytest.fixture(scope="module")
def vehicle_db() -> cantools.database.can.Database:
    db = cantools.database.load_file(str(VEHICLE_DBC))
    assert isinstance(db, cantools.database.can.Database)
    return db


def default_decoder() -> VehicleSignalDecoder:
    return VehicleSignalDecoder(VEHICLE_DBC, speed="VEHICLE_SPEED.SPEED", speed_unit="km/h",
                                yaw_rate="YAW_RATE.YAW_RATE", yaw_rate_unit="deg/s")


def speed_frame(db: Any, kmh: float, counter: int = 0) -> can.Message:
    msg = db.get_message_by_name("VEHICLE_SPEED")
    return can.Message(arbitration_id=msg.frame_id, is_extended_id=False,
                       data=msg.encode({"SPEED": kmh, "COUNTER": counter}))


def yaw_frame(db: Any, deg_s: float, counter: int = 0) -> can.Message:
    msg = db.get_message_by_name("YAW_RATE")
    return can.Message(arbitration_id=msg.frame_id, is_extended_id=False,
                       data=msg.encode({"YAW_RATE": deg_s, "COUNTER": counter}))


class RecordingFactory:
    """The real bus factory, keeping the buses it made (to pull one away) and able to fail."""

    def __init__(self, failures: int = 0) -> None:
        self.buses: list[can.BusABC] = []
        self.failures = failures

    def __call__(self, interface: str, channel: str, can_filters: Any, **kw: Any) -> can.BusABC:
        if self.failures > 0:
            self.failures -= 1
            raise can.CanInitializationError(f"{channel}: No such device (injected)")
        bus = can.Bus(interface=interface, channel=channel, can_filters=can_filters, **kw)
        self.buses.append(bus)
        return bus


@pytest.fixture
def virtual_channel() -> Iterator[tuple[str, can.BusABC]]:
    name = channel_name()
    car = can.Bus(interface="virtual", channel=name)
    yield name, car
    car.shutdown()


# ------------------------------------------------------------------ decoder


def test_decoder_names_the_dbc_and_signal_on_bad_configuration(tmp_path: Path) -> None:
    with pytest.raises(VehicleCanConfigError, match=r"vehicle\.dbc: VEHICLE_SPEED\.SPED: "
                                                    r"message VEHICLE_SPEED has no signal 'SPED' "
                                                    r"\(did you mean SPEED\?\)"):
        VehicleSignalDecoder(VEHICLE_DBC, speed="VEHICLE_SPEED.SPED", speed_unit="km/h",
                             yaw_rate="YAW_RATE.YAW_RATE", yaw_rate_unit="deg/s")
    with pytest.raises(VehicleCanConfigError, match="no message 'YAW'"):
        VehicleSignalDecoder(VEHICLE_DBC, speed="VEHICLE_SPEED.SPEED", speed_unit="km/h",
                             yaw_rate="YAW.YAW_RATE", yaw_rate_unit="deg/s")
    with pytest.raises(VehicleCanConfigError, match="expected MESSAGE.SIGNAL"):
        VehicleSignalDecoder(VEHICLE_DBC, speed="SPEED", speed_unit="km/h",
                             yaw_rate="YAW_RATE.YAW_RATE", yaw_rate_unit="deg/s")
    bad = tmp_path / "broken.dbc"
    bad.write_text('VERSION ""\nBO_ 416 X: 8 V\n SG_ A : 0|8@1+ (1,0 [0|1] "" CW\n')
    with pytest.raises(VehicleCanConfigError, match=r"broken\.dbc: malformed DBC"):
        VehicleSignalDecoder(bad, speed="X.A", speed_unit="m/s", yaw_rate="X.A",
                             yaw_rate_unit="rad/s")
    with pytest.raises(VehicleCanConfigError, match="DBC file not found"):
        VehicleSignalDecoder(tmp_path / "none.dbc", speed="X.A", speed_unit="m/s",
                             yaw_rate="X.A", yaw_rate_unit="rad/s")


def test_production_dbc_from_opendbc_configured_only_by_names() -> None:
    opendbc = pytest.importorskip("opendbc")
    ford = Path(opendbc.__file__).parent / "dbc" / "ford_lincoln_base_pt.dbc"
    decoder = VehicleSignalDecoder(ford, speed="BrakeSysFeatures.Veh_V_ActlBrk", speed_unit="km/h",
                                   yaw_rate="Yaw_Data_FD1.VehYaw_W_Actl", yaw_rate_unit="rad/s",
                                   yaw_rate_sign=-1)    # Ford: clockwise positive
    db = decoder.database
    yaw_msg = db.get_message_by_name("Yaw_Data_FD1")
    speed_msg = db.get_message_by_name("BrakeSysFeatures")
    name = channel_name()
    sink: Handoff[VehicleSignal] = Handoff()
    with can.Bus(interface="virtual", channel=name) as car, \
            VehicleCanReader(decoder, interface="virtual", channel=name, sink=sink) as reader:
        # a right turn of 0.25 rad/s at 72 km/h, as the car sends it (classic CAN frames)
        yaw = {s.name: 0 for s in yaw_msg.signals} | {"VehYaw_W_Actl": 0.25}
        speed = {s.name: 0 for s in speed_msg.signals} | {"Veh_V_ActlBrk": 72.0}
        assert reader.wait_stats(lambda st: st.opens == 1, WAIT)
        for _ in range(3):
            car.send(can.Message(arbitration_id=yaw_msg.frame_id, is_extended_id=False,
                                 data=yaw_msg.encode(yaw, strict=False)))
            car.send(can.Message(arbitration_id=speed_msg.frame_id, is_extended_id=False,
                                 data=speed_msg.encode(speed, strict=False)))
            car.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\0" * 8))
        assert sink.wait_for(lambda s: len(s) >= 6, WAIT)
        values = {v.kind: v.value for v in sink.snapshot()}
    assert values[SignalKind.SPEED] == pytest.approx(20.0, abs=0.01)
    assert values[SignalKind.YAW_RATE] == pytest.approx(-0.25, abs=2e-4)   # CCW positive


# ------------------------------------------------------------------ reader on a virtual bus


def test_reader_decodes_to_si_on_the_monotonic_clock(virtual_channel: tuple[str, can.BusABC],
                                                     vehicle_db: Any) -> None:
    name, car = virtual_channel
    sink: Handoff[VehicleSignal] = Handoff()
    with VehicleCanReader(default_decoder(), interface="virtual", channel=name, sink=sink) as r:
        assert r.wait_stats(lambda st: st.opens == 1, WAIT)
        t0 = time.monotonic()
        car.send(speed_frame(vehicle_db, 90.0))
        car.send(yaw_frame(vehicle_db, -12.5))
        assert sink.wait_for(lambda s: len(s) == 2, WAIT)
        t1 = time.monotonic()
        assert r.wait_state(LinkState.OK, WAIT)
        speed, yaw = sink.snapshot()
        assert (speed.kind, yaw.kind) == (SignalKind.SPEED, SignalKind.YAW_RATE)
        assert speed.value == pytest.approx(25.0)
        assert yaw.value == pytest.approx(math.radians(-12.5))
        for v in (speed, yaw):     # wall-clock stamps mapped onto the monotonic clock
            assert t0 - 0.005 <= v.t <= t1 + 0.001
        assert r.latest(SignalKind.SPEED) == speed
        assert r.stats.timestamp_fallbacks == 0


def test_raw_sink_sees_every_frame_on_the_monotonic_clock(virtual_channel: tuple[str, can.BusABC],
                                                          vehicle_db: Any) -> None:
    name, car = virtual_channel
    raw: Handoff[can.Message] = Handoff()
    with VehicleCanReader(default_decoder(), interface="virtual", channel=name, raw_sink=raw) as r:
        assert r.wait_stats(lambda st: st.opens == 1, WAIT)
        t0 = time.monotonic()
        car.send(speed_frame(vehicle_db, 50.0))
        car.send(can.Message(arbitration_id=0x321, is_extended_id=False, data=b"\1\2"))
        assert raw.wait_for(lambda s: len(s) == 2, WAIT)
        t1 = time.monotonic()
    frames = raw.snapshot()
    assert [m.arbitration_id for m in frames] == [speed_frame(vehicle_db, 50.0).arbitration_id, 0x321]
    assert all(t0 - 0.005 <= m.timestamp <= t1 + 0.001 for m in frames)


def test_reader_counts_wire_problems_and_never_raises(virtual_channel: tuple[str, can.BusABC],
                                                      vehicle_db: Any) -> None:
    name, car = virtual_channel
    sink: Handoff[VehicleSignal] = Handoff()
    with VehicleCanReader(default_decoder(), interface="virtual", channel=name, sink=sink,
                          reopen_min_s=0.02) as r:
        assert r.wait_stats(lambda st: st.opens == 1, WAIT)
        car.send(can.Message(arbitration_id=0x1A0, is_extended_id=False, data=b"\x01\x02"))
        car.send(can.Message(arbitration_id=0x1A0, is_extended_id=True, data=b"\0" * 4))
        car.send(can.Message(arbitration_id=0x321, is_extended_id=False, data=b"\0" * 8))
        car.send(can.Message(arbitration_id=0x1A1, is_extended_id=False, is_remote_frame=True))
        car.send(can.Message(arbitration_id=0x004, is_error_frame=True))   # controller problems
        car.send(speed_frame(vehicle_db, 10.0))
        assert r.wait_stats(lambda st: st.frames == 6, WAIT)
        st = r.stats
        counts = (st.wrong_length, st.ignored, st.error_frames, st.decoded, st.bus_off)
        assert counts == (1, 3, 1, 1, 0)
        car.send(can.Message(arbitration_id=0x040, is_error_frame=True))   # bus-off: reopen
        assert r.wait_stats(lambda st: st.bus_off == 1 and st.opens == 2, WAIT)
        car.send(speed_frame(vehicle_db, 20.0))
        assert sink.wait_for(lambda s: s[-1].value == pytest.approx(20.0 / 3.6), WAIT)


def test_stale_signals_are_reported(virtual_channel: tuple[str, can.BusABC],
                                    vehicle_db: Any) -> None:
    name, car = virtual_channel
    sink: Handoff[VehicleSignal] = Handoff()
    with VehicleCanReader(default_decoder(), interface="virtual", channel=name, sink=sink,
                          stale_s=0.2) as r:
        assert r.wait_state(LinkState.STALE, WAIT)           # nothing received yet
        car.send(speed_frame(vehicle_db, 50.0))
        assert sink.wait_for(lambda s: len(s) == 1, WAIT)
        assert r.state_at(time.monotonic()) is LinkState.STALE   # yaw rate still missing
        car.send(yaw_frame(vehicle_db, 1.0))
        assert r.wait_state(LinkState.OK, WAIT)
        newest = max(v.t for v in sink.snapshot())
        oldest = min(v.t for v in sink.snapshot())
        assert r.state_at(oldest + 0.19) is LinkState.OK
        assert r.state_at(oldest + 0.21) is LinkState.STALE    # speed older than 200 ms
        assert r.state_at(newest + 0.5) is LinkState.STALE
        assert r.wait_state(LinkState.STALE, WAIT)             # the car went quiet


def test_vanished_interface_is_reopened_with_backoff(virtual_channel: tuple[str, can.BusABC],
                                                     vehicle_db: Any) -> None:
    name, car = virtual_channel
    sink: Handoff[VehicleSignal] = Handoff()
    factory = RecordingFactory(failures=2)     # the interface is not there at first
    with VehicleCanReader(default_decoder(), interface="virtual", channel=name, sink=sink,
                          reopen_min_s=0.02, reopen_max_s=0.05, bus_factory=factory) as r:
        assert r.wait_stats(lambda st: st.opens == 1, WAIT)
        assert r.stats.open_failures == 2
        factory.buses[0].shutdown()          # the interface disappears under the reader
        assert r.wait_stats(lambda st: st.bus_lost == 1 and st.opens == 2, WAIT)
        car.send(speed_frame(vehicle_db, 36.0))
        assert sink.wait_for(lambda s: len(s) == 1, WAIT)
        assert sink.snapshot()[0].value == pytest.approx(10.0)


# ------------------------------------------------------------------ writer -> HMI


def hmi_codec() -> HmiCodec:
    return HmiCodec(CONFIG / "appliance.dbc", 0x4C0, 0x4C1, channel="can0")


def collect_hmi(bus: can.BusABC, codec: HmiCodec, until: Any, timeout: float = WAIT) -> list[Any]:
    """Receive HMI frames (as an HMI would) until ``until(decoded list)`` holds."""
    got: list[Any] = []
    deadline = time.monotonic() + timeout
    while not until(got) and time.monotonic() < deadline:
        msg = bus.recv(0.1)
        if msg is not None and msg.arbitration_id in (0x4C0, 0x4C1):
            got.append((msg.arbitration_id, codec.decode(msg.arbitration_id, msg.data), msg))
    return got


def test_writer_sends_status_and_warnings_and_logs_them(tmp_path: Path) -> None:
    name = channel_name()
    codec = hmi_codec()
    log_path = tmp_path / "can_out.log"
    with can.Bus(interface="virtual", channel=name) as hmi:
        writer = HmiCanWriter(codec, interface="virtual", channel=name, period_s=0.05,
                              log_path=log_path).start()
        try:
            writer.publish(status=HmiStatus(state=1, frame_rate_hz=30.0, latency_ms=8.0))
            writer.publish(warning=HmiWarning(2, 17, 1.4, 9.5, 0.2))
            got = collect_hmi(hmi, codec, lambda g: sum(1 for i, _, _ in g if i == 0x4C0) >= 3)
            writer.publish(warning=HmiWarning(0))
            got += collect_hmi(hmi, codec, lambda g: any(
                i == 0x4C0 and d.payload.level == 0 for i, d, _ in g))
        finally:
            writer.stop()
    assert all(d.crc_ok for _, d, _ in got)
    warnings = [d for i, d, _ in got if i == 0x4C0]
    assert [w.payload.level for w in warnings[:3]] == [2, 2, 2] and warnings[-1].payload.level == 0
    first = warnings[0].payload
    assert isinstance(first, HmiWarning) and (first.level, first.track_id) == (2, 17)
    assert (first.ttc_s, first.distance_m, first.bearing_rad) == pytest.approx((1.4, 9.5, 0.2),
                                                                              abs=1e-3)
    for fid in (0x4C0, 0x4C1):          # rolling counters without gaps
        counters = [d.counter for i, d, _ in got if i == fid]
        assert counters == [(counters[0] + k) % 16 for k in range(len(counters))]
    st = writer.stats
    assert st.sent >= len(got) and st.dropped_queue_full == 0 and writer.state is LinkState.STOPPED
    logged = list(can.LogReader(str(log_path)))
    assert len(logged) == st.sent
    received = [(m.arbitration_id, bytes(m.data)) for _, _, m in got]
    assert [(m.arbitration_id, bytes(m.data)) for m in logged][:len(received)] == received
    stamps = [m.timestamp for m in logged]
    assert all(b >= a for a, b in zip(stamps, stamps[1:]))
    assert abs(stamps[-1] - time.monotonic()) < 60.0      # monotonic send times
    assert all(m.channel == "can0" for m in logged)


def test_full_transmit_queue_drops_and_counts_without_blocking() -> None:
    name = channel_name()
    factory = RecordingFactory(failures=10**9)     # the HMI bus is down
    writer = HmiCanWriter(hmi_codec(), interface="virtual", channel=name, tx_queue=4,
                          reopen_min_s=0.02, reopen_max_s=0.05, bus_factory=factory).start()
    try:
        for k in range(40):                         # 40 level changes: 40 warnings at once
            before = writer.stats.updates
            writer.publish(warning=HmiWarning(1 + k % 2, 1))
            assert writer.wait_stats(lambda st: st.updates > before, WAIT)
        st = writer.stats
        assert st.produced >= 40 and st.dropped_queue_full == st.produced - 4
        assert writer.state is LinkState.LOST and st.open_failures >= 1
        factory.failures = 0                        # the bus comes back
        with can.Bus(interface="virtual", channel=name) as hmi:
            assert writer.wait_state(LinkState.OK, WAIT)
            writer.publish(warning=HmiWarning(0))
            got = collect_hmi(hmi, hmi_codec(), lambda g: any(i == 0x4C0 for i, _, _ in g))
        assert got and writer.stats.expired + writer.stats.sent >= 4
    finally:
        writer.stop()


def test_writer_reopens_a_bus_that_vanished() -> None:
    name = channel_name()
    factory = RecordingFactory()
    codec = hmi_codec()
    with can.Bus(interface="virtual", channel=name) as hmi, \
            HmiCanWriter(codec, interface="virtual", channel=name, period_s=0.02,
                         reopen_min_s=0.02, reopen_max_s=0.05, bus_factory=factory) as writer:
        assert writer.wait_stats(lambda st: st.sent >= 2, WAIT)
        factory.buses[0].shutdown()                 # the interface goes away under the writer
        assert writer.wait_stats(lambda st: st.bus_lost == 1 and st.opens == 2, WAIT)
        sent = writer.stats.sent
        assert writer.wait_stats(lambda st: st.sent >= sent + 2, WAIT)
        got = collect_hmi(hmi, codec, lambda g: len(g) >= 2)
        assert all(d.crc_ok for _, d, _ in got) and writer.state is LinkState.OK
        assert writer.stats.send_errors >= 1


# ------------------------------------------------------------------ udp_multicast


def test_reader_and_writer_over_udp_multicast(vehicle_db: Any) -> None:
    port = 40000 + os.getpid() % 20000
    kw: dict[str, Any] = {"port": port}
    group = "239.74.163.9"
    try:
        car = can.Bus(interface="udp_multicast", channel=group, **kw)
    except (can.CanError, OSError) as exc:
        pytest.skip(f"udp_multicast unavailable here ({exc}); as root: ip link set lo up; "
                    "ip route add 224.0.0.0/4 dev lo")
    sink: Handoff[VehicleSignal] = Handoff()
    codec = hmi_codec()
    try:
        with VehicleCanReader(default_decoder(), interface="udp_multicast", channel=group,
                              bus_kwargs=kw, sink=sink) as reader, \
                HmiCanWriter(codec, interface="udp_multicast", channel=group,
                             bus_kwargs=kw) as writer:
            assert reader.wait_stats(lambda st: st.opens == 1, WAIT)
            assert writer.wait_state(LinkState.OK, WAIT)
            car.send(speed_frame(vehicle_db, 18.0))
            car.send(yaw_frame(vehicle_db, 3.0))
            assert sink.wait_for(lambda s: len(s) == 2, WAIT)
            assert [v.value for v in sink.snapshot()] == pytest.approx([5.0, math.radians(3.0)])
            writer.publish(warning=HmiWarning(1, 2, 2.5, 30.0, -0.1))
            got = collect_hmi(car, codec, lambda g: any(i == 0x4C0 for i, _, _ in g))
            warning = next(d for i, d, _ in got if i == 0x4C0)
            assert warning.crc_ok and warning.payload.level == 1 and warning.payload.track_id == 2
            # the HMI frames on the same bus (the reader may see them after the car does)
            assert reader.wait_stats(lambda st: st.ignored >= 1, WAIT)
    finally:
        car.shutdown()


# ------------------------------------------------------------------ SocketCAN (vcan)


def vcan_channel() -> str:
    channel = os.environ.get("CW_VCAN_CHANNEL", "vcan0")
    try:
        with socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW) as s:
            s.bind((channel,))
    except (OSError, AttributeError) as exc:
        pytest.skip(f"SocketCAN {channel} unavailable: {exc}")
    return channel


@pytest.mark.vcan
def test_reader_and_writer_on_socketcan(vehicle_db: Any, tmp_path: Path) -> None:
    channel = vcan_channel()
    sink: Handoff[VehicleSignal] = Handoff()
    codec = hmi_codec()
    with can.Bus(interface="socketcan", channel=channel) as car, \
            VehicleCanReader(default_decoder(), interface="socketcan", channel=channel,
                             sink=sink) as reader, \
            HmiCanWriter(codec, interface="socketcan", channel=channel,
                         log_path=tmp_path / "can_out.log") as writer:
        assert reader.wait_stats(lambda st: st.opens == 1, WAIT)
        t0 = time.monotonic()
        car.send(speed_frame(vehicle_db, 72.0))
        car.send(yaw_frame(vehicle_db, -5.0))
        car.send(can.Message(arbitration_id=0x555, is_extended_id=False, data=b"\0"))
        assert sink.wait_for(lambda s: len(s) == 2, WAIT)
        t1 = time.monotonic()
        speed, yaw = sink.snapshot()
        assert speed.value == pytest.approx(20.0) and yaw.value == pytest.approx(math.radians(-5.0))
        assert all(t0 - 0.005 <= v.t <= t1 + 0.001 for v in (speed, yaw))   # kernel stamps mapped
        assert reader.stats.ignored == 0           # kernel filters kept 0x555 away
        writer.publish(warning=HmiWarning(2, 9, 1.0, 12.0, 0.0))
        got = collect_hmi(car, codec, lambda g: any(i == 0x4C0 for i, _, _ in g))
        assert next(d for i, d, _ in got if i == 0x4C0).crc_ok


def test_a_socketcan_interface_that_cannot_open_names_the_likely_cause() -> None:
    import errno

    from drivers.vehicle_can import open_error

    cases = {
        errno.EAFNOSUPPORT: "this kernel has no SocketCAN",
        errno.ENODEV: "no network interface can7",
        errno.ENETDOWN: "can7 is down",
    }
    for code, cause in cases.items():
        text = open_error("socketcan", "can7", OSError(code, os.strerror(code)))
        assert text.startswith(f"cannot open socketcan:can7: [Errno {code}]") and cause in text
    # other errors and other interfaces: python-can's text alone
    assert open_error("socketcan", "can7", OSError(errno.EPERM, "x")).endswith("] x")
    assert open_error("virtual", "v", OSError(errno.ENODEV, "x")).endswith("] x")
    # and what the reader reports on this machine for a channel that is not there: without
    # SocketCAN in the kernel (errno 97) or without the interface (errno 19)
    with VehicleCanReader(default_decoder(), interface="socketcan", channel="cw-no-such-can",
                          reopen_min_s=0.05, reopen_max_s=0.1) as r:
        assert r.wait_stats(lambda st: st.open_failures >= 1, WAIT)
        assert r.state is LinkState.LOST
        why = r.stats.last_error
    assert "no SocketCAN" in why or "no network interface cw-no-such-can" in why, why
