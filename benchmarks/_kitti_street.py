"""The kitti-street world, used where it lives: its interpreter, generator and scorer.

The world (``../shared/worlds/kitti-street``, its README) is a second, independent simulator
with its own ``generate.py`` and ``score.py``; nothing of it is copied here. This module
finds an interpreter that runs it, generates the recordings that are missing (its scenarios,
and cars standing or braking in the lane that ``_kitti_street_standing.py`` adds through its
``HOLDOUT_MOVERS`` hook), scores runs
with ``score_all.py --json`` and maps each score to the columns of
:mod:`appliance.evaluation.pooled`:

* ``lead_time_s``, ``false_level2``, ``detection_delay_frames`` (the worst mover),
  ``tracked_fraction``, ``ttc_rel_error`` as score.py computes them (its definitions are
  close to ours, not the same: its README);
* ``L1/min``: score.py's ``level1_count`` (every change to level 1, a level 2 easing to 1
  included) per minute of recording;
* ``distErr``: score.py's best-fitting distance definition of the run;
* ghost tracks and the first caution's lead (``lead1``): score.py has neither (``-``);
  targets: score.py's own pass/fail (lead >= 1.5 s, no false level 2, detection <= 10 frames, TTC error <= 20 %, rotation
  <= 0.05 deg), named as ours where they match.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

MODULES = ("numpy", "scipy", "cv2", "can", "cantools", "opendbc")
PACKAGES = ("numpy", "scipy", "opencv-python-headless", "python-can", "cantools", "opendbc")
REPO = Path(__file__).resolve().parents[1]
STANDING = Path(__file__).resolve().with_name("_kitti_street_standing.py")
# score.py metric -> our target name
TARGET_NAMES = {"lead_time_s": "lead_time", "false_level2": "no_false_level2",
                "detection_delay_frames": "detection", "ttc_rel_error": "ttc_error",
                "rotation_error_deg": "rotation"}


class WorldError(Exception):
    """The world or its interpreter cannot be used (one line)."""


def beside_repository(rel: Path, marker: str) -> Path:
    """``rel`` beside the repository (the main checkout's, when this is a git worktree of it):
    the first candidate that holds ``marker``, else the repository's own."""
    candidates = [REPO / rel]
    common = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--path-format=absolute",
                             "--git-common-dir"], capture_output=True, text=True, check=False)
    if common.returncode == 0 and common.stdout.strip():
        candidates.append(Path(common.stdout.strip()).parent / rel)
    found = next((c for c in candidates if (c / marker).is_file()), candidates[0])
    return found.resolve()


def default_world() -> Path:
    """``../shared/worlds/kitti-street`` beside the repository."""
    return beside_repository(Path("..") / "shared" / "worlds" / "kitti-street", "generate.py")


def check_world(world: Path) -> None:
    missing = [f for f in ("generate.py", "score.py", "score_all.py") if not (world / f).is_file()]
    if missing:
        raise WorldError(f"{world}: not the kitti-street world ({', '.join(missing)} missing)")


def _runs(python: str) -> bool:
    code = "import " + ", ".join(MODULES)
    return subprocess.run([python, "-c", code], capture_output=True, check=False).returncode == 0


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "collision-warning"


def find_python(given: str | None) -> tuple[str, str]:
    """An interpreter with the world's packages and how it was found: the one given, this
    one when it has them, else a venv under the cache directory (created when missing)."""
    if given:
        if not _runs(given):
            raise WorldError(f"--ks-python {given}: cannot import {', '.join(MODULES)}")
        return given, "given with --ks-python"
    if _runs(sys.executable):
        return sys.executable, "this interpreter, which has the world's packages"
    venv = cache_dir() / "ks-venv"
    python = str(venv / "bin" / "python")
    how = f"the venv {venv}"
    if not _runs(python):
        print(f"kitti-street: creating {venv} (pip install {' '.join(PACKAGES)})", flush=True)
        for cmd in ([sys.executable, "-m", "venv", str(venv)],
                    [python, "-m", "pip", "install", "--quiet", *PACKAGES]):
            p = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if p.returncode != 0:
                last = (p.stderr.strip().splitlines() or ["(no message)"])[-1]
                raise WorldError(f"creating {venv} failed: {last}")
        how += ", created now"
    return python, how


def generator(world: Path) -> list[str]:
    """The world's generator, with the standing and braking cars of
    ``_kitti_street_standing.py`` registered through its ``HOLDOUT_MOVERS`` hook."""
    return [str(STANDING), str(world)]


def scenarios(python: str, world: Path) -> list[str]:
    p = subprocess.run([python, *generator(world), "--list"], capture_output=True,
                       text=True, check=False)
    if p.returncode != 0:
        raise WorldError(f"{' '.join(generator(world))} --list failed: {p.stderr.strip()}")
    return [line.split()[0] for line in p.stdout.splitlines() if line.strip()]


def recording_name(scenario: str, seed: int) -> str:
    return f"{scenario}_s{seed}"


def generate(python: str, world: Path, out: Path, wanted: Sequence[tuple[str, int]],
             jobs: int) -> list[str]:
    """Generate the wanted (scenario, seed) recordings that ``out`` lacks; returns errors."""
    missing: dict[int, list[str]] = {}
    for name, seed in wanted:
        if not (out / recording_name(name, seed) / "truth.json").is_file():
            missing.setdefault(seed, []).append(name)
    errors = []
    for seed, names in sorted(missing.items()):
        print(f"kitti-street: generating {len(names)} recordings of seed {seed} "
              f"(30-100 s each per core)", flush=True)
        p = subprocess.run([python, *generator(world), "--out", str(out),
                            "--only", ",".join(names), "--seeds", "1", "--first-seed", str(seed),
                            "--jobs", str(jobs)], capture_output=True, text=True, check=False)
        if p.returncode not in (0, 1):  # 1: a collision flag other than expected, still written
            errors.append(f"generate.py seed {seed}: exit {p.returncode}: "
                          + (p.stderr.strip().splitlines() or ["(no message)"])[-1])
    return errors


def score(python: str, world: Path, recordings: Sequence[Path], runs: Path) -> dict[str, Any]:
    """score_all.py over exactly these recordings: {recording name: score.py's result}."""
    with tempfile.TemporaryDirectory(prefix="ks-score-") as tmp:
        data = Path(tmp) / "data"
        data.mkdir()
        for rec in recordings:
            (data / rec.name).symlink_to(rec.resolve(), target_is_directory=True)
        out = Path(tmp) / "score.json"
        p = subprocess.run([python, str(world / "score_all.py"), str(data), str(runs),
                            "--json", str(out)], capture_output=True, text=True, check=False)
        if not out.is_file():
            raise WorldError(f"score_all.py exit {p.returncode}: "
                             + (p.stderr.strip().splitlines() or ["(no message)"])[-1])
        return {r["recording"]: r for r in json.loads(out.read_text())}


def duration_s(recording: Path) -> float:
    """Last minus first capture time in frames.csv."""
    with (recording / "frames.csv").open(newline="") as fh:
        times = [float(row["t"]) for row in csv.DictReader(fh)]
    return times[-1] - times[0] if len(times) > 1 else 0.0


def as_evaluation(r: dict[str, Any], seconds: float) -> dict[str, Any]:
    """score.py's result for one run in the shape of ``appliance.evaluation.report``'s result."""
    m = r["metrics"]

    def value(k: str) -> Any:
        return (m.get(k) or {}).get("value")

    def status(k: str) -> str | None:
        return (m.get(k) or {}).get("status")

    if status("false_level2") is None or value("false_level2") is None:
        return {"scenario": r["scenario"], "error": "score.py: warnings.jsonl missing or unread"}
    objects = []
    if status("detection_delay_frames") in ("PASS", "FAIL"):
        objects.append({"detection_delay_frames": value("detection_delay_frames"),
                        "tracked_fraction": value("tracked_fraction")})
    l1 = int(value("level1_count") or 0)
    minutes = seconds / 60.0
    return {
        "scenario": r["scenario"],
        "collision": bool(r["collision"]),
        "duration_s": round(seconds, 3),
        "objects": objects,
        "lead_time_s": value("lead_time_s"),
        "false_level2": int(value("false_level2")),
        "level1_onsets": l1,
        "level1_per_min": round(l1 / minutes, 3) if minutes > 0 else None,
        "level1_on_truth_course": None,
        "worst_detection_delay_frames": value("detection_delay_frames"),
        "ttc_rel_error_median": value("ttc_rel_error"),
        "distance_rel_error_median": value("distance_rel_error"),
        "ghost_tracks": None,
        "ghost_track_frames": None,
        "targets": {ours: {"PASS": True, "FAIL": False}.get(status(k) or "")
                    for k, ours in TARGET_NAMES.items()},
    }
