"""Replay is the main regression test: simulated drives in, warnings compared with references.

Regenerate the references deliberately with ``.venv/bin/python -m tests.golden --update``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.golden import GOLDEN, differences, reference, run_golden


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_golden_replay(name: str, tmp_path: Path) -> None:
    warnings = run_golden(name, tmp_path)
    assert differences(warnings, reference(name)) == []
    # every confirmed track says why it warns or not; the track behind a raised level says so
    rows = [json.loads(x) for x in (tmp_path / f"{name}-run" / "tracks.jsonl").read_text().splitlines()]
    assert all(isinstance(tr.get("reason"), str) and tr["reason"] for r in rows for tr in r["tracks"])
    names = {1: "caution", 2: "warning"}
    for w in warnings:
        if w["level"] > 0:
            reasons = {tr["id"]: tr["reason"] for tr in rows[w["frame"]]["tracks"]}
            if w["track"] in reasons:
                assert reasons[w["track"]].startswith(names[w["level"]]), (w, reasons)


def test_the_comparison_can_fail() -> None:
    want = [{"frame": 100, "level": 2, "ttc_s": 1.5}]
    assert differences([{"frame": 101, "level": 2, "ttc_s": 1.6}], want) == []
    assert differences([{"frame": 110, "level": 2, "ttc_s": 1.5}], want)
    assert differences([{"frame": 100, "level": 1, "ttc_s": 1.5}], want)
    assert differences([], want)
