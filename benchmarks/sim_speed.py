"""Simulator speed: rendered frames/s at 640x480 on one core, writing included.

``python -m benchmarks sim_speed [--duration S] [--seed N] [--video mkv|avi|png] [--scenarios a,b]``

For each scenario: build the drive (textures, street, sensors; reported apart as
set-up), then render every frame and write the recording (FFV1 video, CAN log, PTU,
truth.json) with ``cv2.setNumThreads(1)``. frames/s = frames / time of that loop.
The machine is shared, so both wall-clock and process-CPU rates are printed; the
CPU rate is what one core of this machine sustains, the wall rate what the load
around it allowed. The target is >= 25 frames/s (median over the scenarios).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

TARGET_FPS = 25.0

if TYPE_CHECKING:
    from appliance.sim.drive import SimStep, SimulatedDrive


def _timed(drive: SimulatedDrive, render_s: list[float]) -> Iterator[SimStep]:
    """The drive's steps, with the CPU time spent producing each one recorded."""
    it = iter(drive)
    while True:
        c0 = time.process_time()
        try:
            step = next(it)
        except StopIteration:
            return
        render_s.append(time.process_time() - c0)
        yield step


def main(argv: list[str]) -> int:
    from appliance.sim.drive import SimulatedDrive
    from appliance.sim.recorder import write_recording
    from appliance.sim.scenarios import SCENARIOS

    ap = argparse.ArgumentParser(prog="python -m benchmarks sim_speed")
    ap.add_argument(
        "--duration", type=float, default=4.0, help="seconds of drive per scenario (default 4)"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--video", choices=("mkv", "avi", "png"), default="mkv")
    ap.add_argument("--scenarios", help="comma-separated names (default: all)")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    names = args.scenarios.split(",") if args.scenarios else list(SCENARIOS)
    print(
        f"simulator speed, 640x480, one core (cv2.setNumThreads(1)), "
        f"{args.duration:g} s per scenario, "
        f"video {args.video}, seed {args.seed}"
    )
    print(
        f"{'scenario':<32}{'frames':>7}{'setup s':>9}{'wall fps':>10}{'cpu fps':>9}"
        f"{'render ms':>11}{'write ms':>10}"
    )
    wall_fps, cpu_fps = [], []
    with tempfile.TemporaryDirectory(prefix="cw-sim-speed-") as tmp:
        for name in names:
            t0 = time.perf_counter()
            drive = SimulatedDrive(name, args.seed, args.duration)
            setup = time.perf_counter() - t0
            render_s: list[float] = []
            w0, c0 = time.perf_counter(), time.process_time()
            write_recording(drive, Path(tmp) / name, args.video, steps=_timed(drive, render_s))
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            n = drive.n_frames
            wall_fps.append(n / wall)
            cpu_fps.append(n / cpu)
            render_ms = 1000.0 * float(np.median(render_s))
            write_ms = 1000.0 * (cpu - sum(render_s)) / n
            print(
                f"{name:<32}{n:>7}{setup:>9.2f}{wall_fps[-1]:>10.1f}{cpu_fps[-1]:>9.1f}{render_ms:>11.1f}"
                f"{write_ms:>10.1f}"
            )
    med_wall, med_cpu = float(np.median(wall_fps)), float(np.median(cpu_fps))
    print(f"{'median':<32}{'':>7}{'':>9}{med_wall:>10.1f}{med_cpu:>9.1f}")
    verdict = "meets" if med_cpu >= TARGET_FPS else "MISSES"
    print(
        f"target >= {TARGET_FPS:g} frames/s (one core, writing included): {verdict} it "
        f"(cpu {med_cpu:.1f}, wall {med_wall:.1f} at this load)"
    )
    return 0
