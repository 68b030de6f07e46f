"""The HMI CAN writer (drivers/hmi_can.py) on real SocketCAN, read by can-utils ``candump``.

What an HMI integrator sees on vcan1 (the HMI bus): every frame decodes with
config/appliance.dbc, the counter rolls by one per message, the CRC-8 SAE J1850
matches, the status heartbeat keeps 10 Hz. Runs inside the vcan VM or on a
kernel with vcan1 up (see README); elsewhere it skips with the reason.
"""

from __future__ import annotations

import re
from itertools import pairwise
from pathlib import Path
from typing import cast

import can
import cantools
import numpy as np
import pytest
from crccheck.crc import Crc8SaeJ1850
from vcan_vm.peer import (
    HMI_BUS,
    Candump,
    ip_link,
    require_root,
    require_socketcan,
    require_tools,
    restored_vcan,
)

from appliance.config import Config, load_config, resource_path
from drivers.hmi_can import HmiCanWriter
from drivers.hmi_codec import HmiCodec, HmiStatus, HmiWarning
from drivers.link import LinkState

pytestmark = [pytest.mark.vcan,
              pytest.mark.filterwarnings("error::pytest.PytestUnhandledThreadExceptionWarning")]

WAIT_S = 10.0
PERIOD_TOLERANCE_S = 0.010  # median period within 10 ms of 100 ms, under software emulation


@pytest.fixture(scope="module")
def cfg() -> Config:
    return load_config()


@pytest.fixture(scope="module")
def appliance_db() -> cantools.database.can.Database:
    db = cantools.database.load_file(str(resource_path("appliance.dbc")))
    assert isinstance(db, cantools.database.can.Database)
    return db


def writer_for(cfg: Config, log: Path) -> HmiCanWriter:
    h = cfg.hmi_can
    codec = HmiCodec(resource_path(h.dbc), h.warning_id, h.status_id, channel=HMI_BUS)
    return HmiCanWriter(codec, interface="socketcan", channel=HMI_BUS, period_s=h.period_s,
                        log_path=log, reopen_min_s=0.1, reopen_max_s=0.5)


def check_frames(frames: list[can.Message], db: cantools.database.can.Database,
                 cfg: Config) -> dict[int, list[dict[str, float]]]:
    """Every frame is one of the two HMI ids, decodes, has its CRC and a rolling counter."""
    ids = {cfg.hmi_can.warning_id: "CollisionWarning", cfg.hmi_can.status_id: "ApplianceStatus"}
    decoded: dict[int, list[dict[str, float]]] = {i: [] for i in ids}
    for m in frames:
        assert m.arbitration_id in ids and not m.is_extended_id and m.dlc == 8, m
        data = bytes(m.data)
        assert Crc8SaeJ1850.calc(data[:7]) == data[7], f"CRC wrong in {m}"
        values = db.get_message_by_name(ids[m.arbitration_id]).decode(data, decode_choices=False)
        decoded[m.arbitration_id].append(cast(dict[str, float], values))
    for ident, rows in decoded.items():
        counters = [int(v["Counter"]) for v in rows]
        steps = {(b - a) % 16 for a, b in pairwise(counters)}
        assert steps <= {1}, f"0x{ident:X} counters {counters}"
    return decoded


def test_hmi_frames_as_candump_sees_them(tmp_path: Path, cfg: Config,
                                         appliance_db: cantools.database.can.Database) -> None:
    require_socketcan()
    require_tools("candump", "stdbuf")
    with Candump(HMI_BUS) as dump:
        dump.sync()
        with writer_for(cfg, tmp_path / "can_out.log") as writer:
            writer.publish(status=HmiStatus(state=1, frame_rate_hz=29.5, latency_ms=41.2))
            assert writer.wait_stats(lambda s: s.sent >= 5, WAIT_S), writer.stats
            writer.publish(warning=HmiWarning(1, 7, ttc_s=3.2, distance_m=25.0, bearing_rad=0.1))
            assert writer.wait_stats(lambda s: s.sent >= 15, WAIT_S), writer.stats
            writer.publish(warning=HmiWarning(2, 7, ttc_s=1.5, distance_m=12.5, bearing_rad=-0.05))
            assert writer.wait_stats(lambda s: s.sent >= 25, WAIT_S), writer.stats
            writer.publish(warning=HmiWarning(0, 0))
            assert writer.wait_stats(lambda s: s.sent >= 35, WAIT_S), writer.stats
        stats = writer.stats
        assert dump.wait_for(lambda lines: len(lines) >= stats.sent + 1, WAIT_S)
        frames = dump.stop()
    assert len(frames) == stats.sent and stats.dropped_queue_full == 0 and stats.send_errors == 0
    decoded = check_frames(frames, appliance_db, cfg)

    # what was sent is what the writer logged in can_out.log
    logged = list(can.CanutilsLogReader(str(tmp_path / "can_out.log")))
    assert [(m.arbitration_id, bytes(m.data)) for m in logged] == \
        [(m.arbitration_id, bytes(m.data)) for m in frames]

    # warnings: caution, then warning, repeated while > 0, then one "cleared"
    warnings = decoded[cfg.hmi_can.warning_id]
    levels = "".join(str(int(v["Level"])) for v in warnings)
    assert re.fullmatch(r"1{2,}2{2,}0", levels), levels
    first = warnings[0]
    assert (first["TrackId"], first["TimeToCollision"], first["Distance"]) == (7, 3.2, 25.0)
    assert first["Bearing"] == pytest.approx(np.degrees(0.1), abs=0.05)
    assert warnings[-1]["TrackId"] == 0

    # status heartbeat at 10 Hz, stamped by the kernel as candump received it
    status = [m for m in frames if m.arbitration_id == cfg.hmi_can.status_id]
    gaps = np.diff([m.timestamp for m in status])
    assert abs(float(np.median(gaps)) - cfg.hmi_can.period_s) <= PERIOD_TOLERANCE_S, gaps
    span = status[-1].timestamp - status[0].timestamp
    assert abs(len(gaps) - span / cfg.hmi_can.period_s) <= 1.0, (len(gaps), span)
    assert all(v["State"] == 1 and v["FrameRate"] == 29.5 and v["Latency"] == 41.2
               for v in decoded[cfg.hmi_can.status_id][1:])
    # warning repeats (same level > 0) at 10 Hz too
    sent_w = [m for m in frames if m.arbitration_id == cfg.hmi_can.warning_id]
    repeat = [b.timestamp - a.timestamp
              for a, b, la, lb in zip(sent_w, sent_w[1:], levels, levels[1:]) if la == lb != "0"]
    assert len(repeat) >= 2 and abs(float(np.median(repeat)) - cfg.hmi_can.period_s) <= PERIOD_TOLERANCE_S


def test_hmi_writer_survives_its_bus_going_down(tmp_path: Path, cfg: Config,
                                                appliance_db: cantools.database.can.Database
                                                ) -> None:
    require_socketcan()
    require_tools("candump", "stdbuf")
    require_root()
    with restored_vcan(HMI_BUS), writer_for(cfg, tmp_path / "can_out.log") as writer:
        writer.publish(status=HmiStatus(state=1))
        assert writer.wait_stats(lambda s: s.sent >= 3, WAIT_S), writer.stats
        ip_link("set", "down", HMI_BUS)
        assert writer.wait_stats(lambda s: s.send_errors >= 1, WAIT_S), writer.stats
        writer.publish(status=HmiStatus(state=2, fault_vehicle_can_stale=True))  # never raises
        ip_link("set", "up", HMI_BUS)
        with Candump(HMI_BUS) as dump:
            dump.sync()
            assert writer.wait_state(LinkState.OK, WAIT_S), writer.stats
            sent = writer.stats.sent
            assert writer.wait_stats(lambda s: s.sent >= sent + 5, WAIT_S), writer.stats
            assert dump.wait_for(lambda lines: len(lines) >= 6, WAIT_S)
            frames = dump.stop()
    decoded = check_frames(frames, appliance_db, cfg)
    assert [v["State"] for v in decoded[cfg.hmi_can.status_id]][-1] == 2
    assert decoded[cfg.hmi_can.status_id][-1]["FaultVehicleCanStale"] == 1
