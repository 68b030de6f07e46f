"""The batch on Ray against replaying one after another: ``python -m benchmarks batch``.

22 recordings (11 scenarios x 2 seeds, ``--duration`` s each, made once with
``collision-warning simulate`` and kept with ``--keep DIR``) are replayed in the same run

* one after another in this process (``engine.run_in_process``: what ``replay`` does, with
  OpenCV's default threads, and no interpreter start per recording), and
* as one batch on a local Ray with ``--workers`` workers (``engine.run_on_ray``), its wall
  time counted from ``ray.init`` (start-up and loading the appliance into the workers
  included) to the last result.

``--rounds N`` repeats the pair in ABBA order (the machine is shared: the load average is
printed before and after). It prints the figures against their targets:

* speed-up: sequential wall / batch wall >= 1.8 with 2 workers;
* Ray's overhead per task <= 0.5 s: on each worker, the time between a result and the start
  of its next task, plus from submission to the first start and from the last end to its
  arrival at the driver, divided by the worker's tasks (and, apart, the round trip of an
  empty task);
* peak memory (RSS) per worker;
* identical results: ``warnings.jsonl``, ``tracks.jsonl``, ``egomotion.csv`` and
  ``can_out.log`` byte for byte between the two;

and the cost of one recording (CPU s, per second of drive, bytes read) that
``docs/fleet.md`` scales to a fleet.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2

from appliance.batch import engine
from appliance.batch.task import Job, JobResult, peak_rss_mb
from appliance.config import load_config
from appliance.recording import Recording

CLI = [sys.executable, "-m", "appliance"]
COMPARED = ("warnings.jsonl", "tracks.jsonl", "egomotion.csv", "can_out.log")


def make_recordings(work: Path, seeds: range, duration: float, jobs: int) -> list[Path]:
    from benchmarks.warning_quality import own_scenarios

    wanted = [(n, s) for n in own_scenarios() for s in seeds]
    recs = [work / f"{n}-seed{s}-{duration:g}s" for n, s in wanted]
    todo = [(n, s, r) for (n, s), r in zip(wanted, recs) if not (r / "truth.json").exists()]

    def one(job: tuple[str, int, Path]) -> None:
        n, s, r = job
        subprocess.run([*CLI, "simulate", n, "--out", str(r), "--seed", str(s), "--duration",
                        str(duration)], check=True, capture_output=True)

    if todo:
        print(f"simulating {len(todo)} recordings of {duration:g} s", flush=True)
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(one, todo))
    return recs


def plan(recs: Sequence[Path], out: Path) -> list[Job]:
    return [Job(str(r), str(out / r.name), evaluate=False) for r in recs]


def sequential(recs: Sequence[Path], out: Path) -> tuple[float, list[JobResult]]:
    cfg = load_config()
    t0 = time.perf_counter()
    results = engine.run_in_process(plan(recs, out), cfg)
    return time.perf_counter() - t0, results


def on_ray(recs: Sequence[Path], out: Path, workers: int
           ) -> tuple[float, engine.RayInfo, list[JobResult], float]:
    cfg = load_config()
    cluster = engine.Cluster(workers=workers)
    t0 = time.perf_counter()
    info = engine.connect(cluster)
    try:
        results = engine.run_on_ray(plan(recs, out), cfg, cluster)
        wall = time.perf_counter() - t0
        empty = empty_task_s(workers)
    finally:
        engine.disconnect()
    return wall, info, results, empty


def empty_task_s(workers: int, n: int = 200) -> float:
    """Wall time per empty task, ``n`` of them on ``workers`` workers (Ray's own cost)."""
    import ray

    noop = ray.remote(num_cpus=1)(engine.warm)
    t0 = time.perf_counter()
    ray.get([noop.remote() for _ in range(n)])
    return (time.perf_counter() - t0) * workers / n


def overhead_per_task(results: Sequence[JobResult]) -> list[float]:
    """Per worker: its wall time from the first submission to its last result at the driver,
    minus the time its tasks ran, divided by its tasks; one figure per task."""
    by_pid: dict[int, list[JobResult]] = defaultdict(list)
    for r in results:
        by_pid[r.pid].append(r)
    first = min(r.submitted for r in results if r.submitted is not None)
    out = []
    for rs in by_pid.values():
        last = max(r.received for r in rs if r.received is not None)
        busy = sum(r.finished - r.started for r in rs)
        out += [(last - first - busy) / len(rs)] * len(rs)
    return out


def differences(recs: Sequence[Path], a: Path, b: Path) -> list[str]:
    return [f"{r.name}/{f}" for r in recs for f in COMPARED
            if (a / r.name / f).read_bytes() != (b / r.name / f).read_bytes()]


def drive_s(rec: Path) -> float:
    t = Recording(rec).frame_times
    return float(t[-1] - t[0]) + (float(t[1] - t[0]) if len(t) > 1 else 0.0)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks batch")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--duration", type=float, default=6.0, help="seconds per recording")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=1, help="sequential/batch pairs, ABBA order")
    ap.add_argument("--keep", metavar="DIR", help="keep the recordings in DIR (made once)")
    args = ap.parse_args(argv)
    try:
        engine.require_ray()
    except engine.RayMissing as exc:
        print(exc, file=sys.stderr)
        return 2
    keep = Path(args.keep) if args.keep else None
    with tempfile.TemporaryDirectory(prefix="batch-bench-") as tmp:
        recs = make_recordings(keep or Path(tmp) / "recs", range(args.seeds), args.duration,
                               args.workers)
        seconds = {r.name: drive_s(r) for r in recs}
        sizes = {r.name: sum(p.stat().st_size for p in r.rglob("*") if p.is_file())
                 for r in recs}
        print(f"{len(recs)} recordings, {sum(seconds.values()):.0f} s of drive; "
              f"load average {os.getloadavg()[0]:.1f}; OpenCV threads {cv2.getNumThreads()} "
              f"sequential, 1 per Ray worker", flush=True)
        seq_walls, ray_walls, ratios, overheads, empties, startups = [], [], [], [], [], []
        shares: list[tuple[float, float]] = []
        worker_peak: dict[str, float] = {}
        diffs: list[str] = []
        ray_results: list[JobResult] = []
        for k in range(args.rounds):
            order = ("seq", "ray") if k % 2 == 0 else ("ray", "seq")
            walls = {}
            for what in order:
                out = Path(tmp) / f"round{k}-{what}"
                if what == "seq":
                    walls["seq"], seq_results = sequential(recs, out)
                else:
                    walls["ray"], info, ray_results, empty = on_ray(recs, out, args.workers)
                    startups.append(info.startup_s)
                    empties.append(empty)
                print(f"  round {k + 1} {what}: {walls[what]:.1f} s", flush=True)
            failed = [r.name for r in seq_results + ray_results if r.status != "done"]
            if failed:
                print(f"failed: {', '.join(failed)}")
                return 1
            diffs += differences(recs, Path(tmp) / f"round{k}-seq", Path(tmp) / f"round{k}-ray")
            seq_walls.append(walls["seq"])
            ray_walls.append(walls["ray"])
            ratios.append(walls["seq"] / walls["ray"])
            # how much of the machine each got: CPU seconds of the replays per wall second
            shares.append((sum(r.cpu_s or 0.0 for r in seq_results) / walls["seq"],
                           sum(r.cpu_s or 0.0 for r in ray_results) / walls["ray"]))
            overheads += overhead_per_task(ray_results)
            for r in ray_results:
                key = f"pid {r.pid}"
                worker_peak[key] = max(worker_peak.get(key, 0.0), r.peak_rss_mb or 0.0)
        print(f"load average after: {os.getloadavg()[0]:.1f}")
        last = Path(tmp) / f"round{args.rounds - 1}-ray"
        written = {r.name: sum(p.stat().st_size for p in (last / r.name).iterdir())
                   for r in recs}
        _report(args, recs, seconds, sizes, written, seq_walls, ray_walls, ratios, startups,
                overheads, empties, worker_peak, diffs, ray_results)
        print("CPUs the replays got (their CPU s per wall s), one after another / batch: "
              + ", ".join(f"{a:.2f} / {b:.2f}" for a, b in shares)
              + f" (of {os.cpu_count()}; the rest went to other processes)")
    return 0 if not diffs else 1


def _report(args: argparse.Namespace, recs: Sequence[Path], seconds: dict[str, float],
            sizes: dict[str, int], written: dict[str, int], seq_walls: list[float], ray_walls: list[float],
            ratios: list[float], startups: list[float], overheads: list[float],
            empties: list[float], worker_peak: dict[str, float], diffs: list[str],
            ray_results: list[JobResult]) -> None:
    med = statistics.median
    ratio = med(ratios)
    over = med(overheads)
    print(f"\n{len(recs)} recordings, {args.workers} workers, {args.rounds} round(s):")
    print(f"  one after another: {med(seq_walls):.1f} s (median); batch on Ray: "
          f"{med(ray_walls):.1f} s, of which start-up {med(startups):.1f} s")
    print(f"  speed-up: {ratio:.2f}x (rounds: {', '.join(f'{x:.2f}' for x in ratios)})  "
          f"target >= 1.8: {'met' if ratio >= 1.8 else 'NOT met'}")
    print(f"  Ray overhead per task: median {over:.3f} s, max {max(overheads):.3f} s; an empty "
          f"task {1e3 * med(empties):.1f} ms  target <= 0.5 s: "
          f"{'met' if over <= 0.5 else 'NOT met'}")
    print("  peak memory per worker: " + ", ".join(f"{k} {v:.0f} MB"
                                                  for k, v in sorted(worker_peak.items()))
          + f"; this process (one after another) {peak_rss_mb():.0f} MB")
    print(f"  results identical (warnings, tracks, egomotion, CAN out): "
          f"{'yes, all ' + str(len(recs)) if not diffs else 'NO: ' + ', '.join(diffs[:5])}")
    cpu = [r.cpu_s for r in ray_results if r.cpu_s is not None]
    per_drive = [r.cpu_s / seconds[r.name] for r in ray_results if r.cpu_s is not None]
    read = [r.read_bytes / seconds[r.name] for r in ray_results if r.read_bytes is not None]
    size = [sizes[r.name] / seconds[r.name] for r in ray_results]
    wall = [(r.finished - r.started) / seconds[r.name] for r in ray_results]
    print(f"\nper recording (last round's batch, medians): CPU {med(cpu):.1f} s, "
          f"{med(per_drive):.2f} CPU s per s of drive; task wall {med(wall):.2f} s per s of "
          f"drive; bytes read {med(read) / 1e6:.2f} MB per s of drive (recording on disk "
          f"{med(size) / 1e6:.2f} MB/s); outputs written "
          f"{med([written[r.name] / seconds[r.name] for r in ray_results]) / 1e3:.1f} kB per s "
          f"of drive; peak RSS {max(r.peak_rss_mb or 0.0 for r in ray_results):.0f} MB")
