"""Health state machine and the systemd notification protocol over a real unix socket."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from appliance.runtime.health import DEGRADED, FAULT, OK, STARTING, Faults, Health
from appliance.runtime.sd_notify import SdNotifier, watchdog_interval_s


def test_states_and_single_report_per_change() -> None:
    h = Health()
    assert h.status.state == STARTING
    assert h.update(True, Faults(), 30.0, 5.0) is not None
    assert h.status.state == OK
    assert h.update(True, Faults(), 30.0, 5.0) is None  # no change, no report
    msg = h.update(True, Faults(vehicle_can_stale=True), 30.0, 5.0)
    assert msg is not None and "degraded" in msg and "vehicle_can_stale" in msg
    assert h.update(True, Faults(vehicle_can_stale=True), 29.0, 6.0) is None
    assert h.update(True, Faults(camera=True, ptu=True), 0.0, 0.0) is not None
    assert h.status.state == FAULT
    assert h.update(True, Faults(overrun=True), 30.0, 5.0) is not None
    assert h.status.state == DEGRADED
    assert h.changes == 4


def test_sd_notify_sends_datagrams(tmp_path: Path) -> None:
    path = str(tmp_path / "notify")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    srv.settimeout(5.0)
    try:
        n = SdNotifier(path)
        assert n.enabled
        assert n.ready("first frame processed")
        assert srv.recv(4096) == b"READY=1\nSTATUS=first frame processed"
        assert n.watchdog()
        assert srv.recv(4096) == b"WATCHDOG=1"
        n.close()
    finally:
        srv.close()


def test_sd_notify_abstract_namespace() -> None:
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind("\0cw-test-notify")
    srv.settimeout(5.0)
    try:
        assert SdNotifier("@cw-test-notify").status("ok")
        assert srv.recv(100) == b"STATUS=ok"
    finally:
        srv.close()


def test_without_notify_socket_it_is_a_no_op(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    n = SdNotifier()
    assert not n.enabled and not n.ready()


def test_gone_socket_is_counted_not_raised(tmp_path: Path) -> None:
    n = SdNotifier(str(tmp_path / "absent"))
    assert not n.watchdog() and n.failures == 1


def test_watchdog_interval(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WATCHDOG_USEC", "5000000")
    monkeypatch.delenv("WATCHDOG_PID", raising=False)
    assert watchdog_interval_s() == 2.5
    monkeypatch.setenv("WATCHDOG_PID", "1")
    assert watchdog_interval_s() is None


def test_a_missing_device_is_reported_again_every_10_s() -> None:
    from appliance.runtime.waiting import StillWaiting

    w = StillWaiting()
    lines = []
    for k in range(251):  # 25 s missing, updates every 0.1 s
        now = 100.0 + 0.1 * k
        lines.append((now, w.update(now, "camera", True, "cannot open /dev/video0")))
    said = [(t, line) for t, line in lines if line is not None]
    assert [round(t - 100.0, 1) for t, _ in said] == [10.0, 20.0]
    assert said[0][1] == "camera: still waiting after 10 s (cannot open /dev/video0); retrying"
    # back, then missing again: counted afresh, other devices apart
    assert w.update(126.0, "camera", False) is None
    assert w.update(127.0, "camera", True, "x") is None
    assert w.update(127.0, "PTU", True, "y") is None
    assert w.update(136.9, "camera", True, "x") is None
    assert w.update(137.0, "camera", True, "x") is not None
    assert w.update(137.0, "PTU", True, "y") is not None


def test_a_status_change_says_what_can_still_be_warned_of() -> None:
    from appliance.runtime.health import Faults, Health

    h = Health()
    assert h.update(True, Faults(), 30.0, 5.0) == "status ok (faults: none)"
    line = h.update(True, Faults(vehicle_can_stale=True), 30.0, 5.0)
    assert line is not None and line.startswith("status degraded (faults: vehicle_can_stale)")
    assert "cautions only" in line
    line = h.update(True, Faults(camera=True), 0.0, 5.0)
    assert line is not None and "no warnings" in line
