"""Runtime figures: replay throughput, and end-to-end latency live at 30 fps VGA.

``python -m benchmarks runtime [--seconds S]``

1. Replay throughput: frames/s of ``replay`` (as fast as possible) on simulated drives.
2. Live latency: the same drives played in real time through the drivers, ring buffers
   and threads (``replay --realtime``); capture time to warning published on the HMI bus,
   median / p99 / max, and the frames dropped because processing fell behind.

Targets: p99 <= 50 ms, 0 dropped frames; replay faster than real time.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import cv2

from appliance.config import load_config
from appliance.recording import Recording, apply_meta
from appliance.replay import replay
from appliance.runtime.realtime_replay import Buses, play_live
from appliance.sim.drive import simulate

DRIVES = (("pedestrian_crossing_nearside", 1), ("bend_static", 2))


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks runtime")
    ap.add_argument("--seconds", type=float, default=8.0, help="duration of each simulated drive")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    base = load_config()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scenario, seed in DRIVES:
            rec_dir = simulate(scenario, Path(tmp) / scenario, seed=seed, duration=args.seconds)
            rec = Recording(rec_dir, defaults=base)
            cfg = apply_meta(base, rec.meta)
            t0 = time.perf_counter()
            fast = replay(rec, cfg, Path(tmp) / f"{scenario}-fast")
            wall = time.perf_counter() - t0
            _, live = play_live(
                Recording(rec_dir, defaults=base),
                cfg,
                Path(tmp) / f"{scenario}-live",
                Buses.private_virtual(),
            )
            e2e = live["processing_ms"]["end_to_end"]
            rows.append(
                {
                    "drive": scenario,
                    "frames": rec.n_frames,
                    "replay_fps": round(fast.frames_processed / wall, 1),
                    "live_processed": live["frames_processed"],
                    "live_dropped": live["frames_dropped"],
                    "latency_median_ms": e2e["median"],
                    "latency_p99_ms": e2e["p99"],
                    "latency_max_ms": e2e["max"],
                    "pipeline_median_ms": live["processing_ms"]["total"]["median"],
                }
            )
    cols = list(rows[0])
    print("  ".join(f"{c:>18}" for c in cols))
    for r in rows:
        print("  ".join(f"{str(r[c]):>18}" for c in cols))
    print(json.dumps({"targets": {"latency_p99_ms": 50, "live_dropped": 0}}))
    return 0
