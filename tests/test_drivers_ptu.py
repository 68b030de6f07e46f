"""The PTU driver against the simulated unit, through a real pseudo-terminal."""

from __future__ import annotations

import math
import os
import select
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import serial

from drivers.handoff import Handoff
from drivers.link import LinkState
from drivers.ptu import AxisCalibration, PtuDriver, PtuLimitError, PtuSample
from drivers.ptu_link import PtuLink, handshake
from drivers.ptu_sim import PtuSimulator
from drivers.ptu_unit import PAN_LIMITS, RESOLUTION_ARCSEC, TILT_LIMITS

RAD_PER_STEP = RESOLUTION_ARCSEC * math.pi / (180.0 * 3600.0)
WAIT = 5.0   # s, generous upper bound for anything to happen on a loaded machine


@pytest.fixture
def sim(tmp_path: Path) -> Iterator[PtuSimulator]:
    s = PtuSimulator(tmp_path / "cw-ptu", seed=1).start()
    yield s
    s.stop()


def make_driver(port: str, sink: Handoff[PtuSample], **kw: Any) -> PtuDriver:
    params: dict[str, Any] = dict(baud=115200, poll_hz=100.0, timeout_s=0.2, retries=1,
                                  reopen_min_s=0.02, reopen_max_s=0.1, sink=sink)
    params.update(kw)
    return PtuDriver(port, **params).start()


def at(sample: PtuSample, expected: tuple[float, float]) -> bool:
    return (sample.pan_rad, sample.tilt_rad) == pytest.approx(expected, abs=1e-12)


def samples_after(sink: Handoff[PtuSample], n: int) -> list[PtuSample]:
    assert sink.wait_for(lambda items: len(items) >= n, WAIT), f"fewer than {n} samples"
    return sink.snapshot()


def test_axis_calibration_round_trip_with_sign_and_offset() -> None:
    cal = AxisCalibration(RAD_PER_STEP, -1, 0.1, -907, 604)
    assert cal.to_rad(0) == pytest.approx(0.1)
    assert cal.to_rad(100) == pytest.approx(0.1 - 100 * RAD_PER_STEP)
    for steps in (-907, -1, 0, 1, 604):
        assert cal.to_steps(cal.to_rad(steps)) == steps
    assert cal.to_steps(0.1 - 10.4 * RAD_PER_STEP) == 10    # rounds, does not truncate
    lo, hi = cal.limits_rad()
    assert lo == pytest.approx(0.1 - 604 * RAD_PER_STEP)
    assert hi == pytest.approx(0.1 + 907 * RAD_PER_STEP)


def test_handshake_poll_and_move(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        # init ran in order with echo and verbose drained (factory state of the unit)
        assert list(sim.received)[:4] == ["ED", "FT", "CI", "I"]
        limits = drv.limits_rad
        assert limits is not None
        assert limits[0] == pytest.approx(tuple(s * RAD_PER_STEP for s in PAN_LIMITS))
        assert limits[1] == pytest.approx(tuple(s * RAD_PER_STEP for s in TILT_LIMITS))
        first = samples_after(sink, 1)[0]
        assert (first.pan_rad, first.tilt_rad) == (0.0, 0.0)
        drv.move_to(0.3, -0.1)
        target = (round(0.3 / RAD_PER_STEP), round(-0.1 / RAD_PER_STEP))
        expected = (target[0] * RAD_PER_STEP, target[1] * RAD_PER_STEP)
        assert sink.wait_for(lambda s: at(s[-1], expected), WAIT)
        assert tuple(round(p) for p in sim.position_steps()) == target
        assert f"PP{target[0]}" in sim.received and f"TP{target[1]}" in sim.received
        ts = [s.t for s in sink.snapshot()]
        assert all(b > a for a, b in zip(ts, ts[1:]))          # monotonic sample times
        st = drv.stats
        assert st.moves == 1 and st.timeouts == 0 and st.garbage == 0 and st.error_replies == 0
    finally:
        drv.stop()
    assert drv.state is LinkState.STOPPED


def test_signs_and_offsets_map_to_the_spec_convention(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink, pan_sign=-1, tilt_sign=-1, pan_offset_rad=0.05)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        assert samples_after(sink, 1)[0].pan_rad == pytest.approx(0.05)
        drv.move_to(0.25, 0.1)
        target = (round(-0.2 / RAD_PER_STEP), round(-0.1 / RAD_PER_STEP))
        expected = (0.05 - target[0] * RAD_PER_STEP, -target[1] * RAD_PER_STEP)
        assert sink.wait_for(lambda s: at(s[-1], expected), WAIT)
        assert tuple(round(p) for p in sim.position_steps()) == target
        assert target[0] < 0 and target[1] < 0
    finally:
        drv.stop()


def test_move_outside_the_unit_limits_is_refused(sim: PtuSimulator) -> None:
    drv = make_driver(sim.port, Handoff())
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        with pytest.raises(PtuLimitError, match="tilt target"):
            drv.move_to(0.0, 0.6)            # TX = 604 steps = 0.542 rad
        with pytest.raises(PtuLimitError, match="not finite"):
            drv.move_to(math.nan, 0.0)
        assert drv.stats.moves == 0
    finally:
        drv.stop()


def test_error_reply_to_a_move_is_counted_and_not_retried(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink, fault_after=1000)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        sim.set_faults(error=1.0)
        drv.move_to(0.2, 0.0)
        steps = round(0.2 / RAD_PER_STEP)
        before = drv.stats.error_replies
        assert drv.wait_stats(lambda st: st.error_replies >= before + 4, WAIT)
        assert list(sim.received).count(f"PP{steps}") == 1
        sim.set_faults(error=0.0)
        n = len(sink)
        assert sink.wait_for(lambda s: len(s) > n + 2, WAIT)
        assert drv.state is LinkState.OK
    finally:
        drv.stop()


def test_garbage_on_the_line_is_dropped_and_counted(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    sim.set_faults(garbage=0.5)
    drv = make_driver(sim.port, sink)
    try:
        samples = samples_after(sink, 40)
        assert all((s.pan_rad, s.tilt_rad) == (0.0, 0.0) for s in samples)   # nothing misread
        st = drv.stats
        assert st.garbage > 5 and sim.stats.garbage_bursts >= st.garbage
        assert drv.state is LinkState.OK
    finally:
        drv.stop()


def test_split_replies_and_latency_within_the_deadline(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    sim.set_faults(split=True, latency_s=0.03)
    drv = make_driver(sim.port, sink)
    try:
        samples_after(sink, 5)
        assert drv.stats.timeouts == 0
    finally:
        drv.stop()


def test_slow_unit_times_out_and_is_retried(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink, timeout_s=0.1, fault_after=1000)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        sim.set_faults(drop=0.3)
        n = len(sink)
        assert sink.wait_for(lambda s: len(s) >= n + 10, WAIT)
        assert drv.stats.timeouts > 0
        assert all((s.pan_rad, s.tilt_rad) == (0.0, 0.0) for s in sink.snapshot())
    finally:
        drv.stop()


def test_silent_unit_raises_the_fault_then_recovers(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink, timeout_s=0.05, retries=0, fault_after=2)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        sim.set_faults(silent=True)
        assert drv.wait_state(LinkState.LOST, WAIT)    # handshake fails: port reopened
        st = drv.stats
        assert st.unresponsive >= 1 and st.timeouts >= 2 and st.init_failures >= 1
        sim.set_faults(silent=False)
        assert drv.wait_state(LinkState.OK, WAIT)
    finally:
        drv.stop()


def test_unplug_and_replug(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        old_device = sim.device
        sim.disconnect()
        assert drv.wait_state(LinkState.LOST, WAIT)
        assert drv.stats.port_lost == 1
        sim.reconnect()
        assert sim.device != old_device or os.path.realpath(sim.port) == sim.device
        assert drv.wait_state(LinkState.OK, WAIT)
        n = sink.put_count
        assert sink.wait_for(lambda _: sink.put_count > n, WAIT)
        assert drv.stats.opens >= 2
    finally:
        drv.stop()


def test_unit_reset_mid_stream_is_detected_and_handshake_rerun(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        drv.move_to(0.1, 0.0)
        assert sink.wait_for(lambda s: abs(s[-1].pan_rad - 0.1) < RAD_PER_STEP, WAIT)
        sim.reset()                          # factory state: echo, verbose, banner, pan 0
        assert drv.wait_stats(lambda st: st.resets_detected >= 1, WAIT)
        assert sink.wait_for(lambda s: s[-1].pan_rad == 0.0, WAIT)
        assert drv.wait_state(LinkState.OK, WAIT)
        assert sim.unit.echo is False and sim.unit.verbose is False
    finally:
        drv.stop()


def test_unsolicited_limit_event_is_counted(sim: PtuSimulator) -> None:
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(sim.port, sink)
    try:
        assert drv.wait_state(LinkState.OK, WAIT)
        sim.emit_limit("P")
        assert drv.wait_stats(lambda st: st.limit_events == 1, WAIT)
        assert drv.state is LinkState.OK
    finally:
        drv.stop()


def test_missing_port_is_retried_with_backoff_until_it_appears(tmp_path: Path) -> None:
    link = tmp_path / "cw-ptu"
    sink: Handoff[PtuSample] = Handoff()
    drv = make_driver(str(link), sink)
    try:
        assert drv.wait_state(LinkState.LOST, WAIT)
        assert drv.wait_stats(lambda st: st.open_failures >= 2, WAIT)
        with PtuSimulator(link, seed=2):
            assert drv.wait_state(LinkState.OK, WAIT)
    finally:
        drv.stop()


def test_sink_errors_do_not_stop_the_driver(sim: PtuSimulator) -> None:
    calls: Handoff[int] = Handoff()

    def bad_sink(sample: PtuSample) -> None:
        calls.put(1)
        raise RuntimeError("consumer bug")

    drv = PtuDriver(sim.port, baud=115200, poll_hz=100.0, sink=bad_sink)
    drv.start()
    try:
        assert calls.wait_for(lambda c: len(c) >= 3, WAIT)
        assert drv.stats.sink_errors >= 3 and drv.state is LinkState.OK
    finally:
        drv.stop()


def test_ptu_sim_command_runs_until_sigterm(tmp_path: Path) -> None:
    link = tmp_path / "ptu-link"
    proc = subprocess.Popen([sys.executable, "-m", "appliance", "ptu-sim", "--link", str(link)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 20.0)
        assert ready, "ptu-sim printed nothing"
        line = proc.stdout.readline().strip()
        device = line.split()[0]
        assert device.startswith("/dev/pts/") and os.path.realpath(link) == device
        # then what to do with it: the [ptu] port to configure (the stable link) and how to stop
        usage = "".join(proc.stdout.readline() for _ in range(4))
        assert f'[ptu]\n  port = "{link}"' in usage and "SIGTERM stops it" in usage, usage
        with serial.Serial(str(link), 115200, timeout=0.05) as port:
            info = handshake(PtuLink(port, timeout_s=1.0))
        assert info.resolution_arcsec == {"P": RESOLUTION_ARCSEC, "T": RESOLUTION_ARCSEC}
        assert info.limits == {"P": PAN_LIMITS, "T": TILT_LIMITS}
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(20.0) == 0
        assert not link.exists()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
