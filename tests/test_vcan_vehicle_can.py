"""The vehicle CAN reader (drivers/vehicle_can.py) on real SocketCAN, can-utils as the peer.

Runs inside the vcan VM (``python -m tests.vcan_vm``) or on a kernel with vcan0 up
(see README); elsewhere it skips with the reason. vcan0 is the vehicle bus.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from pathlib import Path
from typing import Self

import can
import cantools
import numpy as np
import pytest
from vcan_vm.peer import (
    VEHICLE_BUS,
    canplayer,
    ip_link,
    require_root,
    require_socketcan,
    require_tools,
    restored_vcan,
)

from appliance.config import Config, load_config, resource_path
from appliance.recording import Recording, RecordingWriter, meta_from_config
from drivers.link import LinkState
from drivers.vehicle_can import VehicleCanReader
from drivers.vehicle_signals import SignalKind, VehicleSignal, VehicleSignalDecoder

pytestmark = [pytest.mark.vcan,
              pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")]

RATE_HZ = 50.0
SPEED_ID, YAW_ID = 0x1A0, 0x1A1
WRONG_LENGTH_FRAMES = 3


@pytest.fixture(scope="module")
def cfg() -> Config:
    return load_config()


def vehicle_db() -> cantools.database.can.Database:
    db = cantools.database.load_file(str(resource_path("vehicle.dbc")))
    assert isinstance(db, cantools.database.can.Database)
    return db


def write_drive(path: Path, cfg: Config, seconds: float, seed: int = 0) -> dict[str, list[float]]:
    """A recording whose can.log has 50 Hz speed and yaw rate encoded with config/vehicle.dbc.

    Also carries traffic the reader must not decode: another vehicle id and a few
    speed frames of the wrong length. Returns the encoded values in SI units
    (m/s, rad/s CCW), in send order.
    """
    rng = np.random.default_rng(seed)
    dbc_path = resource_path("vehicle.dbc")
    db = vehicle_db()
    meta = meta_from_config(cfg)
    meta = dataclasses.replace(meta, can=dataclasses.replace(meta.can, dbc=str(dbc_path)))
    speed_msg, yaw_msg = db.get_message_by_name("VEHICLE_SPEED"), db.get_message_by_name("YAW_RATE")
    values: dict[str, list[float]] = {"speed": [], "yaw_rate": []}
    t0 = 200.0
    n = int(seconds * RATE_HZ)
    wrong_at = set(rng.choice(np.arange(1, n - 1), WRONG_LENGTH_FRAMES, replace=False).tolist())
    with RecordingWriter(path, meta, video="png") as w:
        for i in range(3):
            w.write_frame(np.zeros((cfg.camera.height, cfg.camera.width), np.uint8), t0 + i / 30)
        for k in range(n):
            t = t0 + k / RATE_HZ
            kmh = round(40.0 + 20.0 * k / n + rng.normal(0.0, 0.3), 2)
            degs = round(8.0 * math.sin(2 * math.pi * k / n) + rng.normal(0.0, 0.05), 2)
            for msg, fields in ((speed_msg, {"SPEED": kmh}), (yaw_msg, {"YAW_RATE": degs})):
                data = msg.encode({**fields, "COUNTER": k % 16})
                w.write_can(can.Message(timestamp=t, arbitration_id=msg.frame_id,
                                        is_extended_id=False, data=data, channel="can0"))
                t += 0.002
            values["speed"].append(kmh / 3.6)
            values["yaw_rate"].append(math.radians(degs))
            w.write_can(can.Message(timestamp=t, arbitration_id=0x0B4, is_extended_id=False,
                                    data=bytes(8), channel="can0"))
            if k in wrong_at:
                w.write_can(can.Message(timestamp=t + 0.001, arbitration_id=SPEED_ID,
                                        is_extended_id=False, data=b"\x01\x02", channel="can0"))
    return values


def decoder_for(recording: Recording) -> VehicleSignalDecoder:
    """The reader's decoder configured only from the recording's ``[can]`` table."""
    c = recording.meta.can
    return VehicleSignalDecoder(c.dbc, speed=c.speed, speed_unit=c.speed_unit,
                                yaw_rate=c.yaw_rate, yaw_rate_unit=c.yaw_rate_unit,
                                yaw_rate_sign=c.yaw_rate_sign)


class Collected:
    """A thread-safe sink for the reader's values."""

    def __init__(self) -> None:
        self.values: list[VehicleSignal] = []
        self._lock = threading.Lock()

    def __call__(self, value: VehicleSignal) -> None:
        with self._lock:
            self.values.append(value)

    def of(self, kind: SignalKind) -> list[VehicleSignal]:
        with self._lock:
            return [v for v in self.values if v.kind is kind]


def test_reader_decodes_a_recording_played_by_canplayer(tmp_path: Path, cfg: Config) -> None:
    require_socketcan()
    require_tools("canplayer")
    truth = write_drive(tmp_path / "drive", cfg, seconds=1.0)
    recording = Recording(tmp_path / "drive")
    n = len(truth["speed"])
    got = Collected()
    with VehicleCanReader(decoder_for(recording), interface="socketcan", channel=VEHICLE_BUS,
                          sink=got) as reader:
        assert reader.wait_stats(lambda s: s.opens >= 1, 10.0)
        t_start = time.monotonic()
        canplayer(recording.path / "can.log", VEHICLE_BUS)
        assert reader.wait_stats(lambda s: s.decoded >= 2 * n and
                                 s.wrong_length >= WRONG_LENGTH_FRAMES, 10.0), reader.stats
        t_end = time.monotonic()
        stats = reader.stats
    speed = got.of(SignalKind.SPEED)
    yaw = got.of(SignalKind.YAW_RATE)
    np.testing.assert_allclose([v.value for v in speed], truth["speed"], rtol=0, atol=1e-9)
    np.testing.assert_allclose([v.value for v in yaw], truth["yaw_rate"], rtol=0, atol=1e-9)
    assert stats.decoded == 2 * n and stats.wrong_length == WRONG_LENGTH_FRAMES
    assert stats.undecodable == 0 and stats.error_frames == 0 and stats.bus_lost == 0
    assert stats.ignored == 0  # SocketCAN filters in the kernel: 0x0B4 never reaches the reader
    # kernel receive times, mapped to the monotonic clock, fall inside the replay
    stamps = np.array([v.t for v in speed])
    assert np.all(np.diff(stamps) >= 0.0)
    assert t_start <= stamps[0] and stamps[-1] <= t_end


class Feed:
    """50 Hz speed (36 km/h) and yaw rate (-2.5 deg/s) on vcan0 from the kernel's
    broadcast manager (can-bcm, through python-can's ``send_periodic``)."""

    def __enter__(self) -> Self:
        self.bus = can.Bus(interface="socketcan", channel=VEHICLE_BUS)
        db = vehicle_db()
        self.tasks = []
        for name, fields in (("VEHICLE_SPEED", {"SPEED": 36.0}), ("YAW_RATE", {"YAW_RATE": -2.5})):
            msg = db.get_message_by_name(name)
            frame = can.Message(arbitration_id=msg.frame_id, is_extended_id=False,
                                data=msg.encode({**fields, "COUNTER": 0}))
            self.tasks.append(self.bus.send_periodic(frame, 1.0 / RATE_HZ))
        return self

    def __exit__(self, *exc: object) -> None:
        for task in self.tasks:
            try:
                task.stop()
            except can.CanOperationError:
                pass  # the interface was deleted: the kernel already dropped the job
        self.bus.shutdown()


def _reader(cfg: Config, sink: Collected) -> VehicleCanReader:
    v = cfg.vehicle_can
    decoder = VehicleSignalDecoder(resource_path(v.dbc), speed=v.speed, speed_unit=v.speed_unit,
                                   yaw_rate=v.yaw_rate, yaw_rate_unit=v.yaw_rate_unit,
                                   yaw_rate_sign=v.yaw_rate_sign)
    return VehicleCanReader(decoder, interface="socketcan", channel=VEHICLE_BUS, stale_s=0.2,
                            reopen_min_s=0.1, reopen_max_s=0.5, sink=sink)


def test_reader_goes_stale_on_link_down_and_recovers_on_up(cfg: Config) -> None:
    require_socketcan()
    require_root()
    got = Collected()
    with restored_vcan(VEHICLE_BUS), Feed(), _reader(cfg, got) as reader:
        assert reader.wait_state(LinkState.OK, 10.0), reader.stats
        ip_link("set", "down", VEHICLE_BUS)
        assert reader.wait_state(LinkState.STALE, 10.0), (reader.state, reader.stats)
        n_down = len(got.values)
        ip_link("set", "up", VEHICLE_BUS)
        t_up = time.monotonic()
        assert reader.wait_state(LinkState.OK, 10.0), (reader.state, reader.stats)
        assert reader.wait_stats(lambda s: s.decoded >= n_down + 10, 10.0)
        stats = reader.stats
    after = [v for v in got.values[n_down:] if v.t >= t_up]
    assert {v.kind for v in after} == {SignalKind.SPEED, SignalKind.YAW_RATE}
    assert all(math.isclose(v.value, 10.0) for v in after if v.kind is SignalKind.SPEED)
    assert all(math.isclose(v.value, math.radians(-2.5))
               for v in after if v.kind is SignalKind.YAW_RATE)
    assert stats.sink_errors == 0


def test_reader_recovers_when_the_interface_is_deleted_and_recreated(cfg: Config) -> None:
    require_socketcan()
    require_root()
    got = Collected()
    with restored_vcan(VEHICLE_BUS), _reader(cfg, got) as reader:
        with Feed():
            assert reader.wait_state(LinkState.OK, 10.0), reader.stats
            ip_link("delete", VEHICLE_BUS)
            assert reader.wait_state(LinkState.LOST, 10.0), (reader.state, reader.stats)
            assert reader.wait_stats(lambda s: s.open_failures >= 1, 10.0), reader.stats
        ip_link("add", "dev", VEHICLE_BUS, "type", "vcan")
        ip_link("set", "up", VEHICLE_BUS)
        n_gone = len(got.values)
        with Feed():  # a new sender: the old broadcast jobs went with the interface
            assert reader.wait_state(LinkState.OK, 15.0), (reader.state, reader.stats)
            assert reader.wait_stats(lambda s: s.decoded >= n_gone + 10, 10.0)
            stats = reader.stats
    assert stats.bus_lost >= 1 and stats.opens >= 2 and stats.sink_errors == 0
    assert len(got.values) > n_gone
