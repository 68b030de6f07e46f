"""``collision-warning demo``: the main job on the embedded default, through the real drivers.

Four simulated drives, three with a collision and one without, are written as drive
recordings (kept under ``OUT/<scenario>/recording``, so they can be replayed and
evaluated afterwards) and then played live, in real time: frames through the
camera interface, vehicle CAN frames on a python-can bus (``vcan0`` where the
kernel has it, else an in-process ``virtual`` bus) read by the real vehicle CAN
reader, the PTU simulator on a pseudo-terminal (turned as the drive's PTU was) polled
by the real PTU driver, and
the warnings sent by the real HMI writer. One line per warning change, a summary
per drive at the end.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

from appliance.config import Config, load_config
from appliance.errors import ApplianceError
from appliance.recording import Recording, apply_meta
from appliance.runtime.realtime_replay import Buses, play_live
from appliance.sim.drive import simulate

# (scenario, seed, duration s): three collision courses (the car with the PTU turned towards
# the intersection; the lead car braking, the classic forward collision), one that ends
# without collision
DRIVES = (
    ("car_crossing_intersection", 1, 6.0),
    ("pedestrian_crossing_nearside", 1, 8.0),
    ("lead_car_braking", 0, 6.0),
    ("pedestrian_stops_at_kerb", 1, 8.0),
)
PROGRESS_EVERY_S = 5.0  # s between two progress lines while simulating


def socketcan_available(channel: str) -> bool:
    """True when a raw CAN socket can bind ``channel`` (kernel CAN support and the interface)."""
    try:
        with socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW) as s:
            s.bind((channel,))
        return True
    except (OSError, AttributeError):
        return False


def demo_buses() -> tuple[Buses, str]:
    if socketcan_available("vcan0"):
        hmi = ("socketcan", "vcan1") if socketcan_available("vcan1") else ("socketcan", "vcan0")
        return Buses(("socketcan", "vcan0"), hmi), f"SocketCAN vcan0 (HMI on {hmi[1]})"
    return Buses.private_virtual(), "python-can virtual buses (no vcan0 on this kernel)"


def _simulate(args: tuple[str, int, float, str]) -> str:
    scenario, seed, duration, out = args
    simulate(scenario, out, seed=seed, duration=duration)
    return out


def written_s(rec: Path) -> float:
    """Seconds of drive a simulator has written to ``rec`` so far (frames.csv grows row by
    row, flushed; a row being written is not counted)."""
    try:
        rows = (rec / "frames.csv").read_text().splitlines()[1:]
        times = [float(r.split(",")[1]) for r in rows[:1] + rows[-2:] if r.count(",") == 1]
    except (OSError, ValueError, IndexError):
        return 0.0
    return max(0.0, max(times) - times[0]) if len(times) > 1 else 0.0


def prepare_recordings(out: Path) -> list[Path]:
    """Simulate the demo drives (in parallel, a progress line every few seconds), reusing
    complete ones from an earlier demo, and say which were reused."""
    todo, paths, reused = [], [], []
    for scenario, seed, duration in DRIVES:
        rec = out / scenario / "recording"
        paths.append(rec)
        try:
            if (rec / "truth.json").is_file():
                Recording(rec)
                reused.append(scenario)
                continue
        except ApplianceError:
            pass
        if rec.exists():
            for p in sorted(rec.rglob("*"), reverse=True):
                p.unlink() if p.is_file() else p.rmdir()
        todo.append((scenario, seed, duration, str(rec)))
    if reused:
        print(f"reusing the recordings of an earlier demo in {out}: {', '.join(reused)} "
              f"(delete {out} to simulate them again)", flush=True)
    if todo:
        total = sum(t[2] for t in todo)
        drives = f"{len(todo)} drives" if len(todo) > 1 else "1 drive"
        print(f"simulating {drives} ({total:.0f} s of driving, on up to 2 cores; "
              f"progress every {PROGRESS_EVERY_S:.0f} s) ...", flush=True)
        t0 = time.monotonic()
        with ProcessPoolExecutor(max_workers=min(2, len(todo))) as pool:
            pending = {pool.submit(_simulate, t) for t in todo}
            while pending:
                done, pending = wait(pending, timeout=PROGRESS_EVERY_S, return_when=FIRST_EXCEPTION)
                for f in done:
                    f.result()  # a failed simulation ends the demo with its error
                parts = [f"{name} {min(written_s(Path(rec)), d):.1f}/{d:.0f} s"
                         for name, _, d, rec in todo]
                print(f"  {time.monotonic() - t0:3.0f} s: {', '.join(parts)}", flush=True)
    return paths


def drive_summary(rec: Recording, run_dir: Path, summary: dict[str, Any]) -> dict[str, Any]:
    truth = rec.truth() or {}
    warnings = [json.loads(x) for x in (run_dir / "warnings.jsonl").read_text().splitlines() if x]
    first_l2 = next((w["t"] for w in warnings if w["level"] == 2), None)
    ctime = truth.get("collision_t")
    lead = None if ctime is None or first_l2 is None else round(ctime - first_l2, 2)
    e2e = summary["processing_ms"]["end_to_end"]
    span = rec.frame_times[-1] - rec.frame_times[0]
    return {
        "scenario": truth.get("scenario", rec.path.parent.name),
        "collision": bool(truth.get("collision")),
        "level2_warnings": sum(1 for w in warnings if w["level"] == 2),
        "level1_warnings": sum(1 for w in warnings if w["level"] == 1),
        "lead_time_s": lead,
        "frames": f"{summary['frames_processed']}/{rec.n_frames}",
        "frame_rate": round(summary["frames_processed"] / span, 1) if span > 0 else None,
        "latency_ms_median": e2e["median"],
        "latency_ms_p99": e2e["p99"],
    }


def main(args: argparse.Namespace) -> int:
    cfg: Config = getattr(args, "cfg", None) or load_config(getattr(args, "config", None))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    buses, bus_text = demo_buses()
    print(
        f"collision-warning demo: {len(DRIVES)} simulated drives, live through the drivers "
        f"({bus_text}; PTU simulator on a pseudo-terminal)",
        flush=True,
    )
    rows = []
    for rec_dir in prepare_recordings(out):
        rec = Recording(rec_dir, defaults=cfg)
        run_cfg = apply_meta(cfg, rec.meta)
        run_dir = rec_dir.parent / "run"
        truth = rec.truth() or {}
        ctime = truth.get("collision_t")
        what = f"collision at t={ctime:.2f}" if ctime else "no collision"
        name = truth.get("scenario", rec_dir.parent.name)
        print(f"\n== {name}: {what} ({rec.n_frames} frames, real time)", flush=True)
        _, summary = play_live(
            rec,
            run_cfg,
            run_dir,
            buses,
            ptu_simulator=True,
            on_event=lambda line: print("  " + line, flush=True),
        )
        rows.append(drive_summary(rec, run_dir, summary))
    print("\nsummary")
    header = (
        "scenario",
        "collision",
        "level2_warnings",
        "lead_time_s",
        "frames",
        "frame_rate",
        "latency_ms_median",
        "latency_ms_p99",
    )
    print("  " + "  ".join(f"{h:>18}" if i else f"{h:<30}" for i, h in enumerate(header)))
    for r in rows:
        print(
            "  "
            + "  ".join(
                f"{str(r[h]):>18}" if i else f"{str(r[h]):<30}" for i, h in enumerate(header)
            )
        )
    (out / "demo_summary.json").write_text(json.dumps(rows, indent=2) + "\n")
    print(
        f"\noutputs in {out}/<scenario>/run (replay or evaluate the recordings next to them); "
        f"{time.monotonic() - t_start:.0f} s",
        flush=True,
    )
    sys.stdout.flush()
    return 0
