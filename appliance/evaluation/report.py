"""``collision-warning evaluate RECORDING RUN_DIR``: score a run against the recording's truth.

Reads ``truth.json`` (through :class:`~appliance.recording.Recording`) and the
run's ``tracks.jsonl`` and ``warnings.jsonl`` (spec formats); prints a table;
writes ``evaluation.json`` and ``timeline.png`` into RUN_DIR. The table's columns
are explained in :mod:`appliance.evaluation.columns` (``evaluate --help``), the
definitions of every score in :mod:`appliance.evaluation.metrics`. A recording
without truth, a run directory without outputs, or a run that did not finish (no
``summary.json``: it stopped half way) is a usage error (exit 2, one line).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TextIO

from appliance.config import Config, load_config
from appliance.errors import UsageError
from appliance.evaluation.columns import COLUMNS
from appliance.evaluation.late import describe, explain_late
from appliance.evaluation.metrics import evaluate
from appliance.evaluation.plot import plot_timeline
from appliance.evaluation.runfiles import Truth, parse_truth, read_tracks, read_warnings
from appliance.recording import Recording


def _open(recording: str | Path) -> tuple[Config, Recording, Truth | None]:
    """The configuration, the recording and its parsed truth (None: it has none)."""
    cfg = load_config()
    rec = Recording(recording, cfg)
    truth_raw = rec.truth()
    truth = None if truth_raw is None else parse_truth(truth_raw, str(rec.path / "truth.json"))
    return cfg, rec, truth


def evaluate_run(recording: str | Path, run_dir: str | Path, plot: bool = True) -> dict[str, Any]:
    """Score ``run_dir`` against ``recording``; writes evaluation.json (and timeline.png)."""
    cfg, rec, truth = _open(recording)
    if truth is None:
        raise UsageError(f"{rec.path}: no truth.json; only simulated recordings can be evaluated")
    run = Path(run_dir)
    if not run.is_dir():
        raise UsageError(f"{run}: run directory not found")
    tracks = read_tracks(run / "tracks.jsonl")
    if not (run / "summary.json").is_file():
        with (run / "tracks.jsonl").open() as fh:
            processed = sum(1 for line in fh if line.strip())
        raise UsageError(
            f"{run}: incomplete run: no summary.json (it stopped after {processed} of "
            f"{rec.n_frames} frames); replay the recording again"
        )
    warnings = read_warnings(run / "warnings.jsonl")
    cam = rec.meta.camera
    result = evaluate(truth, tracks, warnings, rec.frame_times, (cam.width, cam.height),
                      rec.meta.mount, cfg.warning.corridor_margin_m, cfg.warning.ttc_caution_s)
    result["late_reasons"] = explain_late(truth, tracks, rec.frame_times,
                                          (cam.width, cam.height), rec.meta.mount)
    result["recording"] = str(rec.path)
    result["run_dir"] = str(run)
    (run / "evaluation.json").write_text(json.dumps(result, indent=2) + "\n")
    if plot:
        plot_timeline(run / "timeline.png", truth, tracks, warnings, rec.frame_times,
                      rec.meta.mount, result)
    return result


def late_of_run(recording: str | Path, run_dir: str | Path) -> dict[str, Any] | None:
    """What kept a level 2 from being in time in ``run_dir`` (``late.explain_late``), for a
    run scored elsewhere (another world's scorer); None without a collision or a truth."""
    _, rec, truth = _open(recording)
    if truth is None:
        return None
    tracks = read_tracks(Path(run_dir) / "tracks.jsonl")
    cam = rec.meta.camera
    return explain_late(truth, tracks, rec.frame_times, (cam.width, cam.height), rec.meta.mount)


def _fmt(v: Any, spec: str = ".2f") -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "NO"
    return format(v, spec) if isinstance(v, float) else str(v)


TABLE_COLUMNS = tuple((c.key, c.head, c.spec) for c in COLUMNS)


def table_row(r: dict[str, Any]) -> dict[str, str]:
    fractions = [o["tracked_fraction"] for o in r["objects"] if o["tracked_fraction"] is not None]
    vals = dict(r)
    vals["tracked"] = min(fractions) if fractions else None
    failed = [k for k, ok in r["targets"].items() if ok is False]
    vals["pass"] = "ok" if not failed else "FAIL " + ",".join(failed)
    return {head: _fmt(vals.get(key), spec) for key, head, spec in TABLE_COLUMNS}


def print_table(rows: list[dict[str, str]], out: TextIO | None = None) -> None:
    out = out or sys.stdout
    heads = [h for _, h, _ in TABLE_COLUMNS]
    widths = [max(len(h), *(len(r[h]) for r in rows)) if rows else len(h) for h in heads]
    print("  ".join(h.ljust(w) for h, w in zip(heads, widths)), file=out)
    print("  ".join("-" * w for w in widths), file=out)
    for r in rows:
        print("  ".join(r[h].ljust(w) for h, w in zip(heads, widths)), file=out)


def main(args: argparse.Namespace) -> int:
    result = evaluate_run(args.recording, args.run_dir)
    print_table([table_row(result)])
    for o in result["objects"]:
        early = (o["first_detection_frame"] is not None and o["first_eligible_frame"] is not None
                 and o["first_detection_frame"] < o["first_eligible_frame"])
        print(f"  object {o['id']} ({o['class']}): first eligible frame "
              f"{_fmt(o['first_eligible_frame'])}, first detection "
              f"{_fmt(o['first_detection_frame'])}, delay {_fmt(o['detection_delay_frames'])} "
              f"frames{' (tracked before it was eligible)' if early else ''}, "
              f"tracked {_fmt(o['tracked_fraction'], '.0%')}, tracks {o['track_ids']}")
    late = result.get("late_reasons")
    if late is not None:
        lo, hi = late["window_s"]
        print(f"  object {result['colliding_object']}, {lo:g}-{hi:g} s before contact (a level 2 "
              f"then is in time), {late['frames']} frames: {describe(late['counts'])}")
    for c in result["level1_courses"]:
        if c["object"] is None:
            course = "no mover with a known course then"
        elif c["truth_meets_s"] is not None:
            course = (f"object {c['object']}'s truth course meets the corridor "
                      f"{c['truth_meets_s']:.2f} s later")
        else:
            course = (f"the nearest truth course (object {c['object']}) passes "
                      f"{c['truth_closest_m']:.2f} m outside the corridor")
        print(f"  level 1 raised at frame {c['frame']} (t {c['t']:.3f}): {course}")
    run = Path(args.run_dir)
    print(f"wrote {run / 'evaluation.json'} and {run / 'timeline.png'} "
          "(the columns: collision-warning evaluate --help)")
    return 0
