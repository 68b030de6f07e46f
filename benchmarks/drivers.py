"""Driver figures: vehicle CAN decode throughput, PTU position round trip, HMI send latency.

``python -m benchmarks drivers [--quick]``. The process is pinned to one CPU (the
targets' "one core"), so every thread involved (Notifier, sender, simulator) shares
it, as on a loaded appliance. Reported side by side in one run:

1. vehicle CAN: frames/s decoded through a python-can ``virtual`` bus, ``Notifier`` and
   ``VehicleCanReader`` (cantools) with a sink, for the shipped vehicle DBC and the
   Ford DBC from opendbc; next to it the decoder alone and the Notifier alone, so
   the cost split is visible. Target: >= 16,000 frames/s.
2. PTU: round trip of one ``PP`` position query (send to parsed reply) through the
   driver's ``PtuLink`` and a real pseudo-terminal to the simulator, at 115200 baud
   with the wire time emulated (and at 9600 for comparison, and with no wire time:
   the pty and Python alone). Median and p99.
3. HMI: latency from ``HmiCanWriter.publish()`` of a warning change to the frame's
   arrival at a receiving bus (``virtual``; ``udp_multicast`` when available).
   Median, p99, max.
"""

from __future__ import annotations

import logging
import os
import statistics
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import numpy as np
import serial

from drivers.hmi_can import HmiCanWriter
from drivers.hmi_codec import HmiCodec, HmiWarning
from drivers.link import Counters
from drivers.ptu_link import PtuLink, handshake
from drivers.ptu_sim import PtuSimulator
from drivers.vehicle_can import VehicleCanReader, VehicleSignal, VehicleSignalDecoder

CONFIG = Path(__file__).resolve().parents[1] / "config"
TARGET_FPS = 16_000


def pin_one_core() -> str:
    cpus = sorted(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cpus[-1]})
    return f"pinned to CPU {cpus[-1]} of {len(cpus)}"


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q))


# ------------------------------------------------------------------ vehicle CAN


def decoders() -> dict[str, tuple[VehicleSignalDecoder, list[can.Message]]]:
    """Decoder and a representative frame mix for each DBC."""
    out = {}
    veh = VehicleSignalDecoder(CONFIG / "vehicle.dbc", speed="VEHICLE_SPEED.SPEED",
                               speed_unit="km/h", yaw_rate="YAW_RATE.YAW_RATE",
                               yaw_rate_unit="deg/s")
    out["vehicle.dbc"] = (veh, _frames(veh, {"SPEED": 72.0}, {"YAW_RATE": -3.2}))
    try:
        import opendbc
        ford = VehicleSignalDecoder(
            Path(opendbc.__file__).parent / "dbc" / "ford_lincoln_base_pt.dbc",
            speed="BrakeSysFeatures.Veh_V_ActlBrk", speed_unit="km/h",
            yaw_rate="Yaw_Data_FD1.VehYaw_W_Actl", yaw_rate_unit="rad/s", yaw_rate_sign=-1)
        out["ford_lincoln_base_pt.dbc"] = (ford, _frames(ford, {"Veh_V_ActlBrk": 72.0},
                                                         {"VehYaw_W_Actl": 0.1}))
    except ImportError:
        pass
    return out


def _frames(decoder: VehicleSignalDecoder, speed: dict[str, float],
            yaw: dict[str, float]) -> list[can.Message]:
    msgs = []
    for spec, values in zip(decoder.specs, (speed, yaw)):
        m = decoder.database.get_message_by_name(spec.message)
        data = m.encode({s.name: 0.0 for s in m.signals} | values, strict=False)
        msgs.append(can.Message(arbitration_id=m.frame_id, is_extended_id=spec.is_extended,
                                data=data))
    return msgs


def can_throughput(decoder: VehicleSignalDecoder, frames: list[can.Message], n: int) -> float:
    """frames/s through virtual bus + Notifier + reader (decode + sink)."""
    channel = f"bench-{os.getpid()}-{time.monotonic_ns()}"
    rx = can.Bus(interface="virtual", channel=channel)
    with can.Bus(interface="virtual", channel=channel) as tx:
        for k in range(n):
            tx.send(frames[k % len(frames)])
    done = threading.Event()
    seen = [0]

    def sink(value: VehicleSignal) -> None:
        seen[0] += 1
        if seen[0] == n:
            done.set()

    reader = VehicleCanReader(decoder, interface="virtual", channel=channel, sink=sink,
                              bus_factory=lambda *a, **k: rx)
    t0 = time.perf_counter()
    reader.start()
    ok = done.wait(120.0)
    elapsed = time.perf_counter() - t0
    reader.stop()
    if not ok:
        raise RuntimeError(f"only {seen[0]} of {n} frames decoded")
    return n / elapsed


def notifier_only(n: int) -> float:
    """frames/s through virtual bus + Notifier with a listener that only counts."""
    channel = f"bench-n-{os.getpid()}-{time.monotonic_ns()}"
    rx = can.Bus(interface="virtual", channel=channel)
    msg = can.Message(arbitration_id=0x1A0, is_extended_id=False, data=b"\0" * 4)
    with can.Bus(interface="virtual", channel=channel) as tx:
        for _ in range(n):
            tx.send(msg)
    done = threading.Event()
    seen = [0]

    def count(_: can.Message) -> None:
        seen[0] += 1
        if seen[0] == n:
            done.set()

    t0 = time.perf_counter()
    notifier = can.Notifier(rx, [count], timeout=0.05)
    done.wait(120.0)
    elapsed = time.perf_counter() - t0
    notifier.stop()
    rx.shutdown()
    return n / elapsed


def decode_only(decoder: VehicleSignalDecoder, frames: list[can.Message], n: int) -> float:
    t0 = time.perf_counter()
    for k in range(n):
        f = frames[k % len(frames)]
        decoder.decode(f.arbitration_id, f.data, 0.0, f.is_extended_id)
    return n / (time.perf_counter() - t0)


def bench_can(n: int, repeats: int) -> bool:
    print(f"\nvehicle CAN decode throughput ({n} frames per run, median of {repeats}; "
          f"target >= {TARGET_FPS:,} frames/s)")
    print(f"  {'DBC':28s} {'Notifier+reader':>16s} {'decode only':>12s} {'Notifier only':>14s}")
    ok = True
    for name, (decoder, frames) in decoders().items():
        full = statistics.median(can_throughput(decoder, frames, n) for _ in range(repeats))
        dec = statistics.median(decode_only(decoder, frames, n) for _ in range(repeats))
        bare = statistics.median(notifier_only(n) for _ in range(repeats))
        ok &= full >= TARGET_FPS
        print(f"  {name:28s} {full:>13,.0f}/s {dec:>10,.0f}/s {bare:>12,.0f}/s"
              f"   {'meets' if full >= TARGET_FPS else 'MISSES'} target ({full / TARGET_FPS:.2f}x)")
    return ok


# ------------------------------------------------------------------ PTU


def ptu_round_trip(baud: int, wire_time: bool, n: int) -> list[float]:
    """Seconds per PP query (write to parsed reply) through PtuLink and a real pty."""
    with PtuSimulator(seed=0, emulate_wire_time=wire_time) as sim:
        with serial.Serial(sim.device, baud, timeout=0.05) as port:
            link = PtuLink(port, timeout_s=0.5, retries=0, counters=Counters())
            handshake(link)
            times = []
            for _ in range(n):
                t0 = time.perf_counter()
                link.transact("PP")
                times.append(time.perf_counter() - t0)
            counts, _ = link.counts.snapshot()
    if counts.get("timeouts", 0) or counts.get("garbage", 0):
        raise RuntimeError(f"PTU benchmark saw faults: {counts}")
    return times


def bench_ptu(n: int) -> None:
    print(f"\nPTU position query round trip (PP, {n} queries, simulator on a pty)")
    print(f"  {'line':34s} {'median':>8s} {'p99':>8s} {'max':>8s}")
    for label, baud, wire in (("115200 baud, wire time emulated", 115200, True),
                              ("9600 baud, wire time emulated", 9600, True),
                              ("pty only (no wire time)", 115200, False)):
        t = ptu_round_trip(baud, wire, n if baud > 9600 else max(50, n // 4))
        print(f"  {label:34s} {pct(t, 50) * 1e3:6.2f}ms {pct(t, 99) * 1e3:6.2f}ms "
              f"{max(t) * 1e3:6.2f}ms")
    wire_ms = len(b"PP " + b"* 0\r\n") * 10 / 115200 * 1e3
    print(f"  (wire time of 'PP ' + '* 0\\r\\n' at 115200 baud, 10 bits a byte: {wire_ms:.2f} ms; "
          "a real controller's turnaround is not modelled)")


# ------------------------------------------------------------------ HMI


def hmi_latency(interface: str, channel: str, n: int, bus_kwargs: dict[str, Any]) -> list[float]:
    """Seconds from publish() of a warning change to the frame's arrival at a receiver."""
    codec = HmiCodec(CONFIG / "appliance.dbc", 0x4C0, 0x4C1, channel="can0")
    arrived: dict[int, float] = {}
    cond = threading.Condition()
    stop = threading.Event()
    rx = can.Bus(interface=interface, channel=channel, **bus_kwargs)

    def receive() -> None:
        while not stop.is_set():
            msg = rx.recv(0.05)
            if msg is not None and msg.arbitration_id == 0x4C0:
                t = time.perf_counter()
                with cond:
                    arrived[msg.data[1]] = t       # TrackId byte
                    cond.notify_all()

    thread = threading.Thread(target=receive, daemon=True)
    thread.start()
    latencies = []
    with HmiCanWriter(codec, interface=interface, channel=channel, bus_kwargs=bus_kwargs) as w:
        w.publish(warning=HmiWarning(0))
        for k in range(n):
            track = k % 250 + 1
            with cond:
                arrived.pop(track, None)
            t0 = time.perf_counter()
            w.publish(warning=HmiWarning(1 + k % 2, track, 2.0, 20.0, 0.0))
            with cond:
                if cond.wait_for(lambda tr=track: tr in arrived, 2.0):  # type: ignore[misc]
                    latencies.append(arrived[track] - t0)
        dropped = w.stats.dropped_queue_full
    stop.set()
    thread.join(1.0)
    rx.shutdown()
    if len(latencies) < n or dropped:
        raise RuntimeError(f"HMI benchmark: {n - len(latencies)} frames missing, {dropped} dropped")
    return latencies


def bench_hmi(n: int) -> None:
    print(f"\nHMI send latency (publish() of a level change -> frame received, {n} changes)")
    print(f"  {'bus':16s} {'median':>8s} {'p99':>8s} {'max':>8s}")
    runs: list[tuple[str, Callable[[], list[float]]]] = [
        ("virtual", lambda: hmi_latency("virtual", f"bench-hmi-{os.getpid()}", n, {}))]
    try:
        can.Bus(interface="udp_multicast", channel="239.74.163.10", port=43200).shutdown()
        runs.append(("udp_multicast", lambda: hmi_latency(
            "udp_multicast", "239.74.163.10", n, {"port": 43200})))
    except (can.CanError, OSError) as exc:
        print(f"  udp_multicast skipped: {exc}")
    for label, run in runs:
        t = run()
        print(f"  {label:16s} {pct(t, 50) * 1e3:6.2f}ms {pct(t, 99) * 1e3:6.2f}ms "
              f"{max(t) * 1e3:6.2f}ms")


def main(argv: list[str]) -> int:
    quick = "--quick" in argv
    logging.getLogger("drivers").setLevel(logging.ERROR)   # no link-state chatter in the table
    print(f"drivers benchmark ({pin_one_core()}; {'quick' if quick else 'full'} run)")
    ok = bench_can(20_000 if quick else 100_000, 3)
    bench_ptu(200 if quick else 1000)
    bench_hmi(100 if quick else 500)
    return 0 if ok else 1
