"""The obstacle-in-path cue: what it costs per frame, and how far away a standing car is found.

For each stopped-car drive of the simulator (the car standing in the lane, the ego at 30 and at
60 km/h, seed 100 by default: a seed nothing was tuned on), the whole pipeline runs frame by
frame on one core (cv2 threads 1), and the cue's two parts are timed in the same run beside
``perceive`` (vision: flow, refinement, detection):

* **measure**: vision's Lucas-Kanade on the corridor's probes, over ``standing.BASELINE_S``,
  with their windows' structure tensors (``probes.measure_from``);
* **evidence**: the hypotheses' evidence, carried on the road, and the obstacle
  (``standing.standing_step``).

It also reports when and how far away the standing car first becomes an obstacle, and the
time before contact of the first caution and the first warning. Medians over the frames where
the cue runs; the machine is shared, so compare the columns of one run, not runs.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import appliance.decision.decide as decide_module
import appliance.pipeline as pipeline_module
from appliance.config import load_config
from appliance.pipeline import camera_from_config, init_state, step
from benchmarks.vision import open_case, sensor_frames

CLI = [sys.executable, "-m", "appliance"]
SCENARIOS = ("car_stopped_in_lane_30", "car_stopped_in_lane_60")


def timed(log: dict[str, list[float]], key: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        log.setdefault(key, []).append((time.perf_counter() - t0) * 1e3)
        return out
    return wrapper


def run(path: Path) -> dict[str, Any]:
    cfg0 = load_config()
    case = open_case(path, cfg0)
    cfg = case.cfg
    camera = camera_from_config(cfg)
    log: dict[str, list[float]] = {}
    originals = (pipeline_module.measure_from, decide_module.standing_step,
                 pipeline_module.perceive)
    pipeline_module.measure_from = timed(log, "measure", originals[0])
    decide_module.standing_step = timed(log, "evidence", originals[1])
    pipeline_module.perceive = timed(log, "perceive", originals[2])
    first: tuple[float, float] | None = None
    levels: dict[int, float] = {}
    collision_t = case.truth.get("collision_t")
    car = next(o for o in case.truth.get("objects", []) if o.get("class") == "car")
    try:
        state = init_state(cfg, camera)
        for frame, sensors in sensor_frames(case, 10 ** 9):
            state, out, dec = step(state, frame, sensors, cfg, camera)
            ob = state.decision.standing.obstacle if state.decision.standing else None
            if ob is not None and first is None and collision_t is not None:
                gap = car["frames"].get(str(frame.index), {}).get("gap_m")
                first = (collision_t - frame.t, gap if gap is not None else math.nan)
            for ev in out.warnings:
                if ev.level > 0 and ev.level not in levels and collision_t is not None:
                    levels[ev.level] = collision_t - ev.t
    finally:
        (pipeline_module.measure_from, decide_module.standing_step,
         pipeline_module.perceive) = originals
    return {"ms": {k: float(np.median(v)) for k, v in log.items()},
            "frames": len(log.get("perceive", [])), "first": first, "levels": levels,
            "speed_kmh": round(float(car["frames"]["0"]["vel_vehicle"][0]) * -3.6)}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks obstacle", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=100, help="simulator seed (default 100)")
    ap.add_argument("--keep", type=Path, help="keep the recordings in DIR")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    with tempfile.TemporaryDirectory() as tmp:
        where = args.keep if args.keep is not None else Path(tmp)
        print(f"{'drive':28s} {'perceive':>9s} {'measure':>8s} {'evidence':>9s} {'cue/perc':>8s}"
              f"  {'found (s, m before contact)':28s} {'caution':>8s} {'warning':>8s}")
        for name in SCENARIOS:
            rec = where / f"{name}-seed{args.seed}"
            if not (rec / "truth.json").exists():
                subprocess.run([*CLI, "simulate", name, "--out", str(rec), "--seed",
                                str(args.seed)], check=True, capture_output=True)
            r = run(rec)
            ms = r["ms"]
            cue = ms.get("measure", math.nan) + ms.get("evidence", math.nan)
            found = "-" if r["first"] is None else f"{r['first'][0]:.2f} s, {r['first'][1]:.1f} m"
            lv = r["levels"]
            print(f"{name + f' s{args.seed}':28s} {ms.get('perceive', math.nan):8.2f}  "
                  f"{ms.get('measure', math.nan):7.2f}  {ms.get('evidence', math.nan):8.2f}  "
                  f"{cue / ms.get('perceive', math.nan):7.2f}  {found:28s} "
                  f"{lv.get(1, math.nan):7.2f}  {lv.get(2, math.nan):7.2f}")
        print("(ms: medians per frame on one core; caution / warning: first level 1 / 2, "
              "s before contact)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
