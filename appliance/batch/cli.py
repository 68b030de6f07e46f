"""``collision-warning batch RECORDING... --out DIR``: replay (and evaluate) many drives on Ray.

Each recording is one Ray task writing ``DIR/<recording name>/``, the files
``collision-warning replay`` writes. One progress bar; at the end a table, ``DIR/batch.json``
(every recording's figures and costs, the pooled figures) and, with ``--evaluate``,
``DIR/batch.png`` (lead-time and TTC-error distributions). Without ``--address`` a local Ray
with ``--workers`` CPUs runs it; with it, the cluster at that address, reading the
recordings (and writing DIR) at paths its workers see.

A damaged recording fails alone: its row carries the one-line error and the others finish
(exit status 1). Run again with the same DIR to resume: complete runs of the same
configuration and code are not replayed again.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

from appliance import __version__
from appliance.batch import engine, report
from appliance.batch.task import Job, JobResult
from appliance.code_digest import code_digest
from appliance.config import Config, load_config
from appliance.errors import UsageError

JSON_NAME = "batch.json"
PLOT_NAME = "batch.png"


def expand(paths: Sequence[str]) -> list[str]:
    """The recordings named: a directory without ``meta.toml`` whose sub-directories are
    recordings stands for them (sorted). Paths this machine cannot see are kept as given."""
    out: list[str] = []
    for p in paths:
        d = Path(p)
        subs = sorted(s for s in d.iterdir() if (s / "meta.toml").is_file()) \
            if d.is_dir() and not (d / "meta.toml").exists() else []
        out.extend(str(s) for s in subs) if subs else out.append(p)
    return out


def plan(recordings: Sequence[str], out: Path, evaluate: bool, local: bool) -> list[Job]:
    """One job per recording, output in ``out/<recording name>``; names must be unique.

    ``local``: the recordings must exist here (on a cluster only the workers may see them).
    """
    if not recordings:
        raise UsageError("no recordings given")
    out = out.absolute()
    seen: dict[str, str] = {}
    jobs = []
    for rec in recordings:
        if local and not Path(rec).is_dir():
            raise UsageError(f"{rec}: not a recording directory (not found or not a directory)")
        # absolute as this machine sees it: workers elsewhere need the same path
        path = Path(rec).resolve() if local else Path(rec).absolute()
        if path.name in seen:
            raise UsageError(f"{rec}: same name as {seen[path.name]}; both would write "
                             f"{out / path.name}")
        seen[path.name] = rec
        jobs.append(Job(recording=str(path), out_dir=str(out / path.name), evaluate=evaluate))
    return jobs


def _progress(total: int) -> tuple[engine.OnResult, object]:
    from tqdm import tqdm

    bar = tqdm(total=total, unit="rec", file=sys.stderr, disable=None, desc="batch")
    failed = 0

    def on_result(r: JobResult) -> None:
        nonlocal failed
        failed += r.status == "failed"
        bar.set_postfix_str(f"{r.name} {r.status}" + (f", {failed} failed" if failed else ""))
        bar.update(1)

    return on_result, bar


def main(args: argparse.Namespace) -> int:
    cfg: Config = getattr(args, "cfg", None) or load_config(args.config)
    local = args.address is None
    workers = args.workers if args.workers is not None or not local else len(
        os.sched_getaffinity(0))
    cluster = engine.Cluster(address=args.address, workers=workers)
    out = Path(args.out)
    jobs = plan(expand(args.recordings) if local else args.recordings, out, args.evaluate, local)
    engine.require_ray()  # a missing Ray is reported before anything is written
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{out}: cannot create the output directory ({exc.strerror})") from None
    started = datetime.now(UTC).isoformat(timespec="seconds")
    t0 = time.perf_counter()
    info = engine.connect(cluster)
    try:
        print(f"{len(jobs)} recordings on Ray {info.version} ({info.address}: {info.nodes} "
              f"node(s), {info.cpus:g} CPUs) -> {out}", file=sys.stderr, flush=True)
        on_result, bar = _progress(len(jobs))
        try:
            results = engine.run_on_ray(jobs, cfg, cluster, on_result)
        finally:
            bar.close()  # type: ignore[attr-defined]
    finally:
        engine.disconnect()
    doc = report.batch_document(results, {
        "started": started,
        "wall_s": round(time.perf_counter() - t0, 3),
        "arguments": {"out": str(out), "config": args.config, "evaluate": args.evaluate,
                      "address": args.address, "workers": args.workers},
        "version": __version__,
        "code_digest": code_digest(),
        "config_digest": cfg.digest(),
        "ray": {"version": info.version, "address": info.address, "cpus": info.cpus,
                "nodes": info.nodes, "startup_s": info.startup_s, "workers": workers},
    })
    report.write_json(out / JSON_NAME, doc)
    written = [out / JSON_NAME]
    if doc["pooled"] is not None:
        from appliance.batch.plot import plot_batch

        plot_batch(out / PLOT_NAME, report.evaluated(results))
        written.append(out / PLOT_NAME)
    print("\n".join(report.report_lines(results, doc)))
    print(f"wrote {' and '.join(str(p) for p in written)} in {doc['wall_s']:.1f} s")
    return 1 if doc["failed"] else 0
