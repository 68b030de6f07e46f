"""The real peers of the in-guest tests: can-utils processes and ``ip link``.

Used by ``tests/test_vcan_*.py``. In the vcan VM (``VCAN_VM=1``) a missing
interface or tool fails the test, because a skip there would be a silent pass;
elsewhere (a developer's machine, the host side of CI) it skips with the reason.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Self

import can
import pytest

IN_VM = os.environ.get("VCAN_VM") == "1"
VEHICLE_BUS = "vcan0"
HMI_BUS = "vcan1"


def _unavailable(reason: str) -> None:
    if IN_VM:
        pytest.fail(f"in the vcan VM: {reason}")
    pytest.skip(f"{reason} (tests/test_vcan_vm.py runs these in the vcan VM)")


def require_socketcan(channels: Sequence[str] = (VEHICLE_BUS, HMI_BUS)) -> None:
    """Skip (fail in the VM) unless a raw CAN socket can bind to each of ``channels``.

    Every test checks both buses by default, so a machine without them reports
    one folded skip line for the whole suite.
    """
    for channel in channels:
        try:
            with socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW) as s:
                s.bind((channel,))
        except OSError as exc:
            _unavailable(f"SocketCAN {channel} unavailable: {exc}")


def require_tools(*names: str) -> None:
    """Skip (fail in the VM) unless every program is on PATH."""
    missing = [n for n in names if shutil.which(n) is None]
    if missing:
        _unavailable(f"{', '.join(missing)} not found (apt-get install can-utils iproute2)")


def require_root() -> None:
    """Skip unless root: the fault tests take interfaces down and delete them."""
    if os.geteuid() != 0:
        _unavailable("needs root to change CAN interfaces (ip link)")


def ip_link(*args: str) -> None:
    """``ip link ARGS``; raises with ip's message on failure."""
    proc = subprocess.run(["ip", "link", *args], capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"ip link {' '.join(args)}: {proc.stderr.strip()}")


def ensure_vcan(channel: str) -> None:
    """Create ``channel`` as a vcan interface if it is missing, and set it up."""
    if not Path("/sys/class/net", channel).exists():
        ip_link("add", "dev", channel, "type", "vcan")
    ip_link("set", "up", channel)


@contextmanager
def restored_vcan(channel: str) -> Iterator[None]:
    """Whatever the test does to ``channel``, it exists and is up again afterwards."""
    try:
        yield
    finally:
        ensure_vcan(channel)


def canplayer(log: Path, channel: str, log_channel: str = "can0",
              extra: Sequence[str] = ()) -> None:
    """Play a candump ``-L`` log onto ``channel`` with can-utils ``canplayer``, at its pace."""
    subprocess.run(["canplayer", *extra, "-I", str(log), f"{channel}={log_channel}"],
                   check=True, capture_output=True, timeout=120)


class Candump:
    """can-utils ``candump -L CHANNEL`` running as a separate process, its lines collected.

    Call :meth:`sync` before sending what it must see: candump has no ready
    signal, so a probe frame is sent until candump prints it.
    """

    PROBE_ID = 0x7FE

    def __init__(self, channel: str, filters: Sequence[str] = ()) -> None:
        """:param filters: candump ``id:mask`` filters; the probe id is always let through."""
        self.channel = channel
        self.lines: list[str] = []
        self._cond = threading.Condition()
        spec = ",".join([channel, *filters, f"{self.PROBE_ID:03X}:7FF"]) if filters else channel
        self._proc = subprocess.Popen(["stdbuf", "-oL", "candump", "-L", spec],
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self._reader = threading.Thread(target=self._read, name="candump-reader", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self._proc.stdout is not None
        for line in self._proc.stdout:
            with self._cond:
                self.lines.append(line.rstrip("\n"))
                self._cond.notify_all()

    def wait_for(self, predicate: Callable[[list[str]], bool], timeout: float) -> bool:
        """Wait until ``predicate(lines)`` holds; False after ``timeout`` s."""
        with self._cond:
            return self._cond.wait_for(lambda: predicate(self.lines), timeout)

    def sync(self, timeout: float = 10.0) -> None:
        """Return once candump is receiving (it printed one of our probe frames)."""
        probe = can.Message(arbitration_id=self.PROBE_ID, is_extended_id=False, data=b"SYNC")
        tag = f"{self.PROBE_ID:03X}#"
        with can.Bus(interface="socketcan", channel=self.channel) as bus:
            for _ in range(int(timeout / 0.1)):
                bus.send(probe)
                if self.wait_for(lambda lines: any(tag in ln for ln in lines), 0.1):
                    return
        raise TimeoutError(f"candump on {self.channel} printed nothing in {timeout} s")

    def stop(self) -> list[can.Message]:
        """Stop candump; every frame it printed except the probes, parsed by python-can."""
        if self._proc.poll() is None:
            self._proc.terminate()
        self._proc.wait(timeout=10)
        self._reader.join(timeout=10)
        return parse_candump([ln for ln in self.lines if f"{self.PROBE_ID:03X}#" not in ln])

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()


def parse_candump(lines: Sequence[str]) -> list[can.Message]:
    """candump ``-L`` lines to messages with python-can's own log reader."""
    with tempfile.NamedTemporaryFile("w", suffix=".log", delete=False) as fh:
        fh.write("".join(f"{ln}\n" for ln in lines))
    try:
        return list(can.CanutilsLogReader(fh.name))
    finally:
        os.unlink(fh.name)
