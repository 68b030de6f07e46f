"""The output directory of a replay: new or empty, or a previous run's to replace.

A replay into a directory that holds an older run would otherwise overwrite part of it and
leave the rest (its annotated video, ``evaluation.json``, ``timeline.png``) beside the new
outputs, and evaluate would then mix the two. So ``replay --out DIR`` wants DIR absent or
empty; with ``--force`` it first removes the files a run and its evaluation write. Anything
else in DIR (a recording, a sub-directory, someone's notes) is never removed: DIR is refused.
"""

from __future__ import annotations

from pathlib import Path

from appliance.errors import UsageError

# what a run writes (docs/interfaces.md, "What a run writes") and what evaluate adds to it
RUN_FILES = frozenset(
    {
        "warnings.jsonl",
        "tracks.jsonl",
        "egomotion.csv",
        "can_out.log",
        "summary.json",
        "evaluation.json",
        "timeline.png",
    }
)
# annotated videos (replay --video), which users usually write next to the run's outputs
VIDEO_SUFFIXES = frozenset({".avi", ".mkv", ".mp4"})


def is_run_file(path: Path) -> bool:
    return path.is_file() and (path.name in RUN_FILES or path.suffix.lower() in VIDEO_SUFFIXES)


def prepare_run_dir(out: str | Path, force: bool, option: str = "--out") -> Path:
    """Create ``out`` for a new run; raise :class:`UsageError` (exit 2, one line) when it is a
    file, cannot be created, or holds files (with ``force``: files that are not a run's)."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{option} {path}: is a file, not a directory")
    entries = sorted(path.iterdir()) if path.is_dir() else []
    if entries:
        if not force:
            raise UsageError(
                f"{option} {path}: not empty (an earlier run?); choose a new directory, "
                "or add --force to replace the earlier run's files"
            )
        foreign = [p for p in entries if not is_run_file(p)]
        if foreign:
            raise UsageError(
                f"{option} {path}: holds {foreign[0].name}, which no run writes; "
                "--force only replaces a run's files: choose another directory"
            )
    try:
        for p in entries:
            p.unlink()
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{option} {path}: cannot prepare the directory: {exc}") from None
    return path
