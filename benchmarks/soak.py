"""Soak: simulated driving in real time for minutes; resident memory growth and drops.

``python -m benchmarks soak [--minutes 10] [--loop-seconds 30]``

A simulated drive of ``--loop-seconds`` is played live (drivers, ring buffers, threads)
over and over, its times shifted by one loop length each round, for ``--minutes``
minutes of continuous driving. Movers jump back at each loop boundary, which only
makes the tracker work harder. RSS is read from /proc after the first loop (warm-up)
and at the end. Target: RSS growth < 10 MB in 10 minutes; no drops
beyond what the overrun counter reports.
"""

from __future__ import annotations

import argparse
import copy
import math
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import cv2
import numpy as np

from appliance.config import load_config
from appliance.messages import Frame
from appliance.recording import PtuTrack, Recording, apply_meta
from appliance.runtime.realtime_replay import Buses, LiveRig, play_live
from appliance.sim.drive import simulate


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return math.nan


class LoopedRecording:
    """A recording repeated ``loops`` times, each round shifted by the loop length."""

    def __init__(self, rec: Recording, loops: int) -> None:
        self.rec = rec
        self.path = rec.path
        self.meta = rec.meta
        t = rec.frame_times
        self.period = float(t[-1] - t[0]) + float(np.median(np.diff(t)))
        self.loops = loops
        self.frame_times = np.concatenate([t + k * self.period for k in range(loops)])
        self.n_frames = len(self.frame_times)

    def frames(self, start: int = 0) -> Iterator[Frame]:
        n = self.rec.n_frames
        for k in range(self.loops):
            for f in self.rec.frames():
                yield Frame(f.index + k * n, f.t + k * self.period, f.image)

    def can_messages(self) -> Iterator[can.Message]:
        for k in range(self.loops):
            for m in self.rec.can_messages():
                m2 = copy.copy(m)
                m2.timestamp = m.timestamp + k * self.period
                yield m2

    def ptu(self) -> PtuTrack | None:
        return None

    def truth(self) -> dict[str, Any] | None:
        return None


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks soak")
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--loop-seconds", type=float, default=30.0)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    base = load_config()
    with tempfile.TemporaryDirectory() as tmp:
        rec_dir = simulate(
            "pedestrian_stops_at_kerb", Path(tmp) / "loop", seed=5, duration=args.loop_seconds
        )
        rec = Recording(rec_dir, defaults=base)
        loops = max(2, math.ceil(args.minutes * 60.0 / args.loop_seconds))
        looped = LoopedRecording(rec, loops)
        cfg = apply_meta(base, rec.meta)
        marks: dict[str, float] = {}

        def on_start(rig: LiveRig) -> None:
            # warm-up: the first loop (buffers, caches and the tracker reach their working size)
            timer = threading.Timer(
                looped.period + 1.0, lambda: marks.__setitem__("warm", rss_mb())
            )
            timer.daemon = True
            timer.start()

        marks["start"] = rss_mb()
        stats, summary = play_live(
            looped,  # type: ignore[arg-type]
            cfg,
            Path(tmp) / "run",
            Buses.private_virtual(),
            on_start=on_start,
        )
        marks["end"] = rss_mb()
    warm = marks.get("warm", marks["start"])
    print(
        f"soak: {loops} x {looped.period:.1f} s = {loops * looped.period / 60:.1f} min of driving"
    )
    print(
        f"frames read {summary['frames_read']}, processed {summary['frames_processed']}, "
        f"dropped (overrun) {summary['frames_dropped']}"
    )
    print(
        f"RSS start {marks['start']:.1f} MB, after warm-up {warm:.1f} MB, "
        f"end {marks['end']:.1f} MB; "
        f"growth after warm-up {marks['end'] - warm:+.1f} MB (target < 10 MB)"
    )
    e2e = summary["processing_ms"]["end_to_end"]
    print(f"latency median {e2e['median']} ms, p99 {e2e['p99']} ms")
    return 0
