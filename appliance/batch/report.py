"""What a batch reports: the per-recording table, the pooled figures and ``batch.json``."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from appliance.batch.task import JobResult
from appliance.evaluation.report import table_row
from appliance.evaluation import pooled

EVALUATION_COLUMNS = ("coll", "detect(fr)", "tracked", "lead(s)", "falseL2", "L1/min", "TTCerr",
                      "distErr", "ghosts", "targets")


def _f(v: float | None, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def recording_row(r: JobResult) -> dict[str, str]:
    """One recording: status, frames, replay time and cost, its evaluation's columns, error."""
    ev = table_row(r.evaluation) if r.evaluation is not None else {}
    row = {
        "recording": r.name,
        "status": r.status,
        "frames": _f(r.frames, "d"),
        "replay s": _f(r.replay_s, ".1f"),
        "CPU s": _f(r.cpu_s, ".1f"),
        "peak MB": _f(r.peak_rss_mb, ".0f"),
        "scenario": ev.get("scenario", "-"),
    }
    row.update({c: ev.get(c, "-") for c in EVALUATION_COLUMNS})
    row["error"] = r.error or ""
    return row


def evaluated(results: Sequence[JobResult]) -> list[dict[str, Any]]:
    """The evaluations, with the recordings whose replay or evaluation failed as errors."""
    out: list[dict[str, Any]] = []
    for r in results:
        if r.evaluation is not None:
            out.append(r.evaluation)
        elif r.status == "failed":
            out.append({"scenario": r.name, "error": r.error})
    return out


def pooled_section(results: Sequence[JobResult]) -> dict[str, Any] | None:
    """Per-scenario rows, the row over every run and the totals (None: nothing evaluated)."""
    evals = evaluated(results)
    if not any("error" not in e for e in evals):
        return None
    return {
        "by_scenario": pooled.aggregate(evals),
        "all": pooled.pooled_row(evals),
        "totals": pooled.totals(evals),
    }


def costs(results: Sequence[JobResult]) -> dict[str, Any]:
    """Per-recording cost of the runs replayed now: CPU s, frames, bytes read; worker peaks."""
    done = [r for r in results if r.status == "done"]
    cpu = [r.cpu_s for r in done if r.cpu_s is not None]
    frames = sum(r.frames or 0 for r in done)
    per_worker: dict[str, float] = {}
    for r in results:
        if r.peak_rss_mb is not None and r.pid:
            key = f"{r.host}:{r.pid}"
            per_worker[key] = max(per_worker.get(key, 0.0), r.peak_rss_mb)
    read = [r.read_bytes for r in done if r.read_bytes is not None]
    return {
        "recordings_replayed": len(done),
        "frames_replayed": frames,
        "cpu_s_total": round(sum(cpu), 3),
        "cpu_s_median": pooled.median(cpu),
        "cpu_ms_per_frame": round(1e3 * sum(cpu) / frames, 2) if cpu and frames else None,
        "read_bytes_total": sum(read) if read else None,
        "peak_rss_mb_per_worker": dict(sorted(per_worker.items())),
    }


def batch_document(results: Sequence[JobResult], header: dict[str, Any]) -> dict[str, Any]:
    """The content of ``batch.json``."""
    return {
        **header,
        "recordings": len(results),
        "done": sum(r.status == "done" for r in results),
        "skipped": sum(r.status == "skipped" for r in results),
        "failed": sum(r.status == "failed" for r in results),
        "costs": costs(results),
        "pooled": pooled_section(results),
        "runs": [asdict(r) for r in results],
    }


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` to ``path`` through a temporary file, so a kill leaves the old or the new."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    os.replace(tmp, path)


def report_lines(results: Sequence[JobResult], doc: dict[str, Any]) -> list[str]:
    """The table printed at the end of a batch."""
    rows = [recording_row(r) for r in results]
    if not any(r.evaluation is not None for r in results):
        rows = [{k: v for k, v in row.items() if k not in ("scenario", *EVALUATION_COLUMNS)}
                for row in rows]
    lines = pooled.format_rows(rows)
    section = doc["pooled"]
    if section is not None:
        lines += ["", "pooled over the evaluated recordings:"]
        lines += pooled.format_rows([*section["by_scenario"], section["all"]])
        lines += [""] + pooled.totals_lines(section["totals"])
    c = doc["costs"]
    lines += ["", f"{doc['done']} replayed, {doc['skipped']} already done, {doc['failed']} failed"
              f" of {doc['recordings']}; {c['cpu_s_total']:.0f} CPU s for "
              f"{c['frames_replayed']} frames"
              + (f" ({c['cpu_ms_per_frame']:.1f} ms/frame)" if c["cpu_ms_per_frame"] else "")]
    return lines
