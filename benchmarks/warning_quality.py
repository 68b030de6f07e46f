"""Warning quality over every simulated scenario: ``python -m benchmarks warning_quality``.

For each scenario of ``collision-warning simulate --list`` and each seed (3 by
default): simulate a recording, replay it, evaluate the run against the truth
(``appliance.evaluate``), then print one row per scenario run and an aggregate
table with the issue's targets:

* collision scenarios: level 2 at least 1.5 s before ``collision_t`` (aim 2.0 s);
* no-collision scenarios: no level-2 warning, at most one level-1 per minute;
* a mover is a confirmed track within 10 frames of being >= 15 px tall, visible and moving
  over the ground (> 0.3 m/s, ``appliance.evaluation.metrics``);
* median relative TTC error <= 20 % and distance error <= 15 % in the last 3 s.

It also counts ghost tracks (confirmed tracks never on a mover, no target) per minute.

Options: ``--seeds N``, ``--scenarios a,b``, ``--keep DIR`` (keep recordings and
runs, with ``timeline.png``; recordings already in DIR are replayed again, not
simulated again), ``--jobs N`` (parallel scenario runs; the machine
is shared, default 1), ``--config FILE`` (passed to replay).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from appliance.errors import ApplianceError
from appliance.evaluate import evaluate_run, print_table, table_row

CLI = [sys.executable, "-m", "appliance"]


def scenarios() -> list[str]:
    out = subprocess.run([*CLI, "simulate", "--list"], capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"simulate --list failed: {out.stderr.strip() or out.stdout.strip()}")
    names = [line.split()[0] for line in out.stdout.splitlines()
             if line.strip() and not line.startswith((" ", "#"))]
    return [n.rstrip(":") for n in names]


def one_run(name: str, seed: int, work: Path, config: str | None, plots: bool) -> dict[str, Any]:
    rec = work / f"{name}-seed{seed}"
    run = work / f"{name}-seed{seed}-run"
    steps = [
        # --force: a kept DIR's earlier run of this recording is replaced
        [*CLI, "replay", str(rec), "--out", str(run), "--no-progress", "--force"]
        + (["--config", config] if config else []),
    ]
    if not (rec / "truth.json").exists():  # a kept recording is reused (the simulator is seeded)
        steps.insert(0, [*CLI, "simulate", name, "--out", str(rec), "--seed", str(seed)])
    for cmd in steps:
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            msg = (p.stderr.strip().splitlines() or ["(no message)"])[-1]
            return {"scenario": name, "seed": seed, "error": f"{cmd[3]} exit {p.returncode}: {msg}"}
    try:
        r = evaluate_run(rec, run, plot=plots)
    except ApplianceError as exc:
        return {"scenario": name, "seed": seed, "error": f"evaluate: {exc}"}
    r["seed"] = seed
    lead = "-" if r["lead_time_s"] is None else f"{r['lead_time_s']:.2f} s"
    print(f"  {name}#{seed}: lead {lead}, false level-2 {r['false_level2']}, "
          f"level-1 onsets {r['level1_onsets']}", flush=True)
    return r


def _med(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def aggregate(results: list[dict[str, Any]]) -> list[dict[str, str]]:
    """One row per scenario over its seeds."""
    rows = []
    for name in dict.fromkeys(r["scenario"] for r in results):
        rs = [r for r in results if r["scenario"] == name and "error" not in r]
        errors = [r for r in results if r["scenario"] == name and "error" in r]
        if not rs:
            rows.append({"scenario": name, "seeds": f"0/{len(errors)}", "coll": "-",
                         "lead min/med": "-", "falseL2": "-", "L1/min max": "-",
                         "detect max": "-", "TTCerr": "-", "distErr": "-", "ghosts/min": "-",
                         "targets": "ERROR " + errors[0]["error"]})
            continue
        coll = rs[0]["collision"]
        leads = [r["lead_time_s"] for r in rs]
        known = [v for v in leads if v is not None]
        delays = [r["worst_detection_delay_frames"] for r in rs if r["objects"]]
        failed = sorted({k for r in rs for k, ok in r["targets"].items() if ok is False})
        l1 = [r["level1_per_min"] for r in rs if r["level1_per_min"] is not None]
        ttc = [r["ttc_rel_error_median"] for r in rs if r["ttc_rel_error_median"] is not None]
        dist = [r["distance_rel_error_median"] for r in rs
                if r["distance_rel_error_median"] is not None]

        def f(v: float | None, spec: str = ".2f") -> str:
            return "-" if v is None else format(v, spec)

        lead_txt = "-"
        if coll:
            lead_txt = (f"{f(min(known))}/{f(_med(known))}" if len(known) == len(leads)
                        else f"MISS {len(leads) - len(known)}")
        rows.append({
            "scenario": name,
            "seeds": f"{len(rs)}/{len(rs) + len(errors)}",
            "coll": "yes" if coll else "no",
            "lead min/med": lead_txt,
            "falseL2": str(sum(r["false_level2"] for r in rs)),
            "L1/min max": "-" if coll or not l1 else f(max(l1)),
            "detect max": "-" if not delays else ("MISS" if None in delays else str(max(delays))),
            "TTCerr": f(_med(ttc), ".0%"),
            "distErr": f(_med(dist), ".0%"),
            "ghosts/min": f(sum(r["ghost_tracks"] for r in rs)
                            / max(sum(r["duration_s"] for r in rs) / 60.0, 1e-9), ".1f"),
            "targets": "ok" if not failed and not errors else
            "FAIL " + ",".join(failed + (["errors"] if errors else [])),
        })
    return rows


def print_rows(rows: list[dict[str, str]]) -> None:
    if not rows:
        return
    heads = list(rows[0])
    widths = [max(len(h), *(len(r[h]) for r in rows)) for h in heads]
    print("  ".join(h.ljust(w) for h, w in zip(heads, widths)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(r[h].ljust(w) for h, w in zip(heads, widths)))


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks warning_quality")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--scenarios", help="comma-separated subset (default: all)")
    ap.add_argument("--keep", metavar="DIR", help="keep recordings and runs in DIR")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--config", help="configuration file passed to replay")
    args = ap.parse_args(argv)
    names = args.scenarios.split(",") if args.scenarios else scenarios()
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="warning_quality-"))
    work.mkdir(parents=True, exist_ok=True)
    jobs = [(n, s) for n in names for s in range(args.seeds)]
    print(f"{len(names)} scenarios x {args.seeds} seeds; work dir {work}", flush=True)
    try:
        with ThreadPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
            results = list(pool.map(
                lambda job: one_run(job[0], job[1], work, args.config, bool(args.keep)), jobs))
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    ok = [r for r in results if "error" not in r]
    print("\nper run:")
    rows = []
    for r in ok:
        row = table_row(r)
        row["scenario"] = f"{r['scenario']}#{r['seed']}"
        rows.append(row)
    print_table(rows)
    for r in results:
        if "error" in r:
            print(f"  {r['scenario']}#{r['seed']}: {r['error']}")
    print("\naggregate over seeds:")
    agg = aggregate(results)
    print_rows(agg)
    coll = [r for r in ok if r["collision"]]
    calm = [r for r in ok if not r["collision"]]
    leads = [r["lead_time_s"] for r in coll]
    print(f"\ncollision runs with level 2 >= 1.5 s before contact: "
          f"{sum(1 for v in leads if v is not None and v >= 1.5)}/{len(coll)}"
          f" (median lead {_med([v for v in leads if v is not None]) or float('nan'):.2f} s)")
    print(f"false level-2 warnings: {sum(r['false_level2'] for r in ok)} "
          f"(no-collision runs with any: {sum(1 for r in calm if r['false_level2'])}/{len(calm)})")
    calm_min = sum(r["duration_s"] for r in calm) / 60.0
    if calm_min > 0:
        print(f"level-1 onsets in no-collision runs: {sum(r['level1_onsets'] for r in calm)} in "
              f"{calm_min:.1f} min ({sum(r['level1_onsets'] for r in calm) / calm_min:.2f}/min); "
              f"{sum(r['level1_on_truth_course'] for r in calm)} of them raised while the truth "
              f"course met the corridor within the caution horizon")
    timely = [r for r in ok for o in r["objects"]
              if o["detection_delay_frames"] is not None and o["detection_delay_frames"] <= 10]
    movers = [o for r in ok for o in r["objects"]]
    print(f"movers confirmed within 10 frames of being >= 15 px tall, visible and moving: "
          f"{len(timely)}/{len(movers)}")
    run_min = sum(r["duration_s"] for r in ok) / 60.0
    if run_min > 0:
        ghosts = sum(r["ghost_tracks"] for r in ok)
        print(f"ghost tracks (confirmed, never on a mover): {ghosts} in {run_min:.1f} min "
              f"({ghosts / run_min:.2f}/min), "
              f"{sum(r['ghost_track_frames'] for r in ok)} track-frames")
    meeting = sum(1 for r in ok if not any(v is False for v in r["targets"].values()))
    print(f"runs meeting every target: {meeting}/{len(results)}")
    return 0 if all(a["targets"] == "ok" for a in agg) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
