"""Real SocketCAN with can-utils as the peer: python-can's socketcan bus on vcan.

Runs inside the vcan VM (``python -m tests.vcan_vm``) or on any kernel with
vcan0/vcan1 up (see README); elsewhere every test skips with the reason.
These pin the kernel and python-can behaviour the drivers rely on.
"""

from __future__ import annotations

import errno
from pathlib import Path

import can
import numpy as np
import pytest
from vcan_vm.peer import (
    HMI_BUS,
    VEHICLE_BUS,
    Candump,
    canplayer,
    ip_link,
    require_root,
    require_socketcan,
    require_tools,
    restored_vcan,
)

pytestmark = pytest.mark.vcan


def _frames(n: int, seed: int) -> list[can.Message]:
    """A seeded mix of 11- and 29-bit data frames with 0-8 data bytes, 2 ms apart."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        extended = bool(rng.random() < 0.3)
        ident = int(rng.integers(0, 1 << 29 if extended else 1 << 11))
        data = bytes(rng.integers(0, 256, int(rng.integers(0, 9)), dtype=np.uint8))
        out.append(can.Message(timestamp=1000.0 + 0.002 * k, arbitration_id=ident,
                               is_extended_id=extended, data=data, channel="can0"))
    return out


def _key(m: can.Message) -> tuple[int, bool, bytes]:
    return m.arbitration_id, m.is_extended_id, bytes(m.data)


def _receive(bus: can.BusABC, n: int, timeout: float = 5.0) -> list[can.Message]:
    got: list[can.Message] = []
    while len(got) < n:
        m = bus.recv(timeout)
        if m is None:
            break
        got.append(m)
    return got


def test_canplayer_frames_reach_python_can(tmp_path: Path) -> None:
    require_socketcan()
    require_tools("canplayer")
    sent = _frames(200, seed=1)
    log = tmp_path / "can.log"
    with can.CanutilsLogWriter(str(log)) as writer:
        for m in sent:
            writer.on_message_received(m)
    with can.Bus(interface="socketcan", channel=VEHICLE_BUS) as bus:
        canplayer(log, VEHICLE_BUS)
        got = _receive(bus, len(sent))
        assert bus.recv(0.2) is None  # nothing beyond what was played
    assert [_key(m) for m in got] == [_key(m) for m in sent]
    assert all(m.channel == VEHICLE_BUS for m in got)
    stamps = np.array([m.timestamp for m in got])
    assert np.all(np.diff(stamps) >= 0)


def test_candump_captures_what_python_can_sends() -> None:
    require_socketcan()
    require_tools("candump", "stdbuf")
    sent = _frames(100, seed=2)
    with Candump(HMI_BUS) as dump, can.Bus(interface="socketcan", channel=HMI_BUS) as bus:
        dump.sync()
        for m in sent:
            bus.send(m)
        assert dump.wait_for(lambda lines: len(lines) >= len(sent) + 1, 10.0)
        got = dump.stop()
    assert [_key(m) for m in got] == [_key(m) for m in sent]
    assert all(m.channel == HMI_BUS for m in got)


def test_candump_filter_sees_only_its_ids() -> None:
    """The HMI integrator's view: ``candump vcan1,4C0:7FF`` shows only that id."""
    require_socketcan()
    require_tools("candump", "stdbuf")
    with Candump(HMI_BUS, filters=["4C0:7FF"]) as dump, \
            can.Bus(interface="socketcan", channel=HMI_BUS) as bus:
        dump.sync()
        for ident in (0x4C0, 0x4C1, 0x4C0, 0x123):
            bus.send(can.Message(arbitration_id=ident, is_extended_id=False, data=b"\x01"))
        assert dump.wait_for(lambda lines: len(lines) >= 3, 5.0)
        got = dump.stop()
    assert [m.arbitration_id for m in got] == [0x4C0, 0x4C0]


def _send_one(channel: str, ident: int) -> None:
    with can.Bus(interface="socketcan", channel=channel) as tx:
        tx.send(can.Message(arbitration_id=ident, is_extended_id=False, data=b"\x2a"))


def test_link_down_then_up_errors_then_delivers_again() -> None:
    require_socketcan()
    require_root()
    with restored_vcan(VEHICLE_BUS), \
            can.Bus(interface="socketcan", channel=VEHICLE_BUS) as rx, \
            can.Bus(interface="socketcan", channel=VEHICLE_BUS) as tx:
        ip_link("set", "down", VEHICLE_BUS)
        with pytest.raises(can.CanOperationError) as sent_down:
            tx.send(can.Message(arbitration_id=0x1A0, is_extended_id=False, data=b"\x00"))
        assert sent_down.value.error_code == errno.ENETDOWN
        with pytest.raises(can.CanOperationError):
            rx.recv(1.0)  # the kernel reports ENETDOWN to the bound socket
        ip_link("set", "up", VEHICLE_BUS)
        tx.send(can.Message(arbitration_id=0x1A0, is_extended_id=False, data=b"\x01"))
        m = rx.recv(2.0)  # the same socket receives again after up
        assert m is not None and m.arbitration_id == 0x1A0 and bytes(m.data) == b"\x01"


def test_link_deleted_and_recreated_needs_a_new_socket() -> None:
    require_socketcan()
    require_root()
    with restored_vcan(VEHICLE_BUS), can.Bus(interface="socketcan", channel=VEHICLE_BUS) as old:
        ip_link("delete", VEHICLE_BUS)
        with pytest.raises(can.CanOperationError):
            old.recv(1.0)  # ENODEV
        with pytest.raises(OSError):
            can.Bus(interface="socketcan", channel=VEHICLE_BUS)
        ip_link("add", "dev", VEHICLE_BUS, "type", "vcan")
        ip_link("set", "up", VEHICLE_BUS)
        with can.Bus(interface="socketcan", channel=VEHICLE_BUS) as new:
            _send_one(VEHICLE_BUS, 0x1A1)
            m = new.recv(2.0)
            assert m is not None and m.arbitration_id == 0x1A1
        assert old.recv(0.3) is None  # the old socket stays unbound: reopen is required
