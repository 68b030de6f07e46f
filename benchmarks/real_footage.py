"""Real footage: false warnings on real images and real camera motion.

Every drive recording under ``--recordings DIR`` (default ``../shared/real`` beside the
repository: a KITTI residential street and a US freeway) is replayed with the embedded default
configuration, or ``--config FILE``. Nothing in these clips threatens the car and they have no
truth, so what they measure is robustness: every level raised is a false one. Per clip:

* its length, frames and frame rate (a real camera is not the simulator's: odd sizes, 10 Hz);
* level-1 and level-2 onsets (a level rising from below it);
* confirmed tracks, their track-frames, and the checks that kept them from warning
  (``tracks.jsonl``'s reasons, figures dropped, as shares of the track-frames): how far the
  clip came from a warning;
* the pipeline's median ms per frame (one replay, all stages).

The totals give the level-1 onsets per minute of real driving, the target being at most one.
Where the default directory is missing the benchmark says so and is skipped.
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
from collections import Counter
from pathlib import Path

from appliance.config import load_config
from appliance.errors import ApplianceError
from appliance.evaluation import metrics
from appliance.evaluation.runfiles import json_rows, read_warnings
from appliance.replay import open_recording, replay
from benchmarks._kitti_street import beside_repository

PROG = "python -m benchmarks real_footage"
TOP_REASONS = 4


def default_recordings() -> Path:
    """``../shared/real`` beside the repository."""
    return beside_repository(Path("..") / "shared" / "real", "README.md")


def onsets(warnings_jsonl: Path) -> tuple[int, int]:
    """Level-1 onsets (a level from 0) and level-2 onsets, as the evaluation counts them."""
    l2, l1 = metrics.onsets(read_warnings(warnings_jsonl))
    return len(l1), len(l2)


def census(tracks_jsonl: Path) -> tuple[int, float, int, Counter[str]]:
    """(frames, seconds, confirmed tracks, track-frames per reason with figures as '#')."""
    reasons: Counter[str] = Counter()
    ids: set[int] = set()
    times: list[float] = []
    for _, row in json_rows(tracks_jsonl):
        times.append(float(row["t"]))
        for tr in row["tracks"]:
            ids.add(int(tr["id"]))
            reasons[re.sub(r"\d+(\.\d+)?", "#", tr.get("reason") or "-")] += 1
    dt = statistics.median(b - a for a, b in zip(times, times[1:])) if len(times) > 1 else 0.0
    seconds = times[-1] - times[0] + dt if times else 0.0
    return len(times), seconds, len(ids), reasons


def clips(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if (p / "meta.toml").is_file())


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog=PROG, description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recordings", metavar="DIR", type=Path,
                    help="directory of drive recordings (default: ../shared/real beside the "
                         "repository)")
    ap.add_argument("--config", help="configuration file passed to every replay")
    args = ap.parse_args(argv)
    root = (args.recordings or default_recordings()).resolve()
    try:
        cfg = load_config(args.config)
    except ApplianceError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    found = clips(root) if root.is_dir() else []
    if not found and args.recordings is None:
        print(f"real_footage skipped: {root}: no drive recordings")
        return 0
    if not found:
        print(f"{PROG}: {root}: no drive recordings (directories with a meta.toml)",
              file=sys.stderr)
        return 2
    print(f"{len(found)} recordings in {root}")
    print(f"{'recording':26s} {'s':>5s} {'frames':>6s} {'fps':>5s} {'L1':>3s} {'L2':>3s} "
          f"{'tracks':>6s} {'tr-fr':>6s} {'ms':>6s}  what kept the tracks from warning")
    status = 0
    total_s = 0.0
    total1 = total2 = 0
    with tempfile.TemporaryDirectory(prefix="real_footage-") as tmp:
        for clip in found:
            out = Path(tmp) / clip.name
            try:
                rec, run_cfg = open_recording(clip, cfg)
                result = replay(rec, run_cfg, out)
            except ApplianceError as exc:
                print(f"{clip.name:26s} error: {exc}")
                status = 1
                continue
            frames, seconds, n_tracks, reasons = census(out / "tracks.jsonl")
            n1, n2 = onsets(out / "warnings.jsonl")
            track_frames = sum(reasons.values())
            ms = statistics.median(result.stage_ms["total"]) if result.stage_ms["total"] else 0.0
            why = ", ".join(f"{r} {100 * n / track_frames:.0f} %"
                            for r, n in reasons.most_common(TOP_REASONS)) or "-"
            fps = frames / seconds if seconds > 0 else 0.0
            print(f"{clip.name:26s} {seconds:5.1f} {frames:6d} {fps:5.1f} {n1:3d} {n2:3d} "
                  f"{n_tracks:6d} {track_frames:6d} {ms:6.1f}  {why}")
            total_s += seconds
            total1 += n1
            total2 += n2
    minutes = total_s / 60.0
    rate = total1 / minutes if minutes > 0 else 0.0
    print(f"real driving {total_s:.1f} s: level-2 onsets {total2} (all false), level-1 onsets "
          f"{total1} ({rate:.2f}/min, target <= 1/min)")
    return status


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
