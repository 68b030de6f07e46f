"""The product's text speaks to users and maintainers, not of how it was developed.

README, docs/, config/, systemd/ and the code of appliance/ and drivers/ carry no numbered work
sessions or rounds, no "issue N", no "the task", no commit hashes and nothing "not kept": the
git log is the history. The patterns are narrow enough to leave ordinary words alone ("task"
of a Ray task, "the issued level", Python's ``round(x, 2)``, CAN data in hex).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("README.md", "docs", "config", "systemd", "appliance", "drivers")
TEXT_SUFFIXES = {".md", ".py", ".toml", ".dbc", ".service", ".rules", ".network", ".sysusers",
                 ".txt", ".cfg", ".ini", ".yaml", ".yml", ".json", ".sh"}

HISTORY = {
    "numbered session": re.compile(r"\bsessions?\s+\d+", re.IGNORECASE),
    # not a benchmark's `--rounds 2` nor its "rounds 1.31 and 1.46" (ratios measured per round)
    "numbered round": re.compile(r"(?<!--)\b(?:work\s+)?rounds?\s+\d+\b(?!\.\d)",
                                 re.IGNORECASE),
    "work round": re.compile(r"\bwork\s+rounds?\b", re.IGNORECASE),
    "issue number": re.compile(r"\bissues?\s+#?\d+", re.IGNORECASE),
    "the issue": re.compile(r"\b(?:the\s+issue|issue's)(?![a-z])", re.IGNORECASE),
    # instructions, not a Ray task ("the task's start", "the CPU the task reserved")
    "the task": re.compile(r"\b(?:see|per)\s+the\s+task\b|\btask\s+brief\b"
                           r"|\bthe\s+task\s+(?:says|said|asks|asked|wants|requires|statement"
                           r"|description)\b", re.IGNORECASE),
    "not kept": re.compile(r"\bnot\s+kept\b", re.IGNORECASE),
    # a git hash: 7-40 lowercase hex digits with at least one digit and one letter (not the
    # code digest a results page names its code by, as summary.json's code_digest does)
    "commit hash": re.compile(r"(?<!digest `)\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b"),
}


def history_words(text: str) -> list[tuple[str, str]]:
    """(pattern name, matched text) of every trace of development history in ``text``."""
    return [(name, m.group(0)) for name, rx in HISTORY.items() for m in rx.finditer(text)]


def product_files() -> list[Path]:
    out: list[Path] = []
    for name in SCANNED:
        path = ROOT / name
        if path.is_file():
            out.append(path)
        elif path.is_dir():
            out.extend(p for p in sorted(path.rglob("*"))
                       if p.is_file() and p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts)
    return out


def test_product_files_carry_no_development_history() -> None:
    files = product_files()
    names = {p.relative_to(ROOT).as_posix() for p in files}
    # the scan reaches what it is meant to: the README, the docs, the default, code of both packages
    assert {"README.md", "docs/interfaces.md", "config/default.toml", "config/appliance.dbc",
            "appliance/pipeline.py", "drivers/camera.py",
            "systemd/collision-warning.service"} <= names
    found = []
    for path in files:
        text = path.read_text(encoding="utf-8")   # whole: a phrase may wrap onto the next line
        for name, rx in HISTORY.items():
            for m in rx.finditer(text):
                lineno = text.count("\n", 0, m.start()) + 1
                found.append(f"{path.relative_to(ROOT)}:{lineno}: {name}: {m.group(0)!r}")
    assert not found, "development history in product files:\n" + "\n".join(found)


@pytest.mark.parametrize(("text", "pattern"), [
    ("with session 19's final code", "numbered session"),
    ("measured in sessions 15 and 16", "numbered session"),
    ("Session 7 found it", "numbered session"),
    ("the work round 3 code", "numbered round"),
    ("as of round 12", "numbered round"),
    ("in the last work round", "work round"),
    ("see issue 6, item 6", "issue number"),
    ("fixes issue #28", "issue number"),
    ("described in the issue's note", "the issue"),
    ("as the issue asks", "the issue"),
    ("see the task brief", "the task"),
    ("see the task", "the task"),
    ("the task says so", "the task"),
    ("as the task asks", "the task"),
    ("a task brief", "the task"),
    ("measured and not kept", "not kept"),
    ("13 and 17 were not kept", "not kept"),
    ("measured and not\n  kept", "not kept"),
    ("in session\n19", "numbered session"),
    ("merged in a23e64b", "commit hash"),
    ("9007b6c26a1cc892ef1c53e7b7e19cb1c30f8c0b", "commit hash"),
])
def test_the_checker_catches_each_pattern(text: str, pattern: str) -> None:
    assert pattern in {name for name, _ in history_words(text)}


@pytest.mark.parametrize("text", [
    "The issued level is the highest over all tracks",
    "each drive runs as a Ray task; tasks are retried",
    "the CPU the task reserved; the task's start, its arguments; rchar of the task",
    "python -m benchmarks batch --keep DIR --rounds 2",
    "a speed-up of 1.38x (rounds 1.31 and 1.46)",
    "round(float(x), 2) and round(t + i * period, 6)",
    "can.log: (1700000000.123456) can0 0B4#00000000001F4E27",
    "warning_id = 0x4C0",
    "a session of live driving; the rounds of the counter",
    "a deadbeef marker and a 1234567 frame count",
    "kept while the TTC stays within threshold",
    "Measured with code digest `84f9e224c6e74148` (the `code_digest` in every run's",
])
def test_the_checker_leaves_ordinary_words_alone(text: str) -> None:
    assert history_words(text) == []
