"""Replay is the main regression test: simulated drives in, warnings compared with references.

Regenerate the references deliberately with ``.venv/bin/python -m tests.golden --update``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.golden import GOLDEN, differences, reference, run_golden


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_golden_replay(name: str, tmp_path: Path) -> None:
    assert differences(run_golden(name, tmp_path), reference(name)) == []


def test_the_comparison_can_fail() -> None:
    want = [{"frame": 100, "level": 2, "ttc_s": 1.5}]
    assert differences([{"frame": 101, "level": 2, "ttc_s": 1.6}], want) == []
    assert differences([{"frame": 110, "level": 2, "ttc_s": 1.5}], want)
    assert differences([{"frame": 100, "level": 1, "ttc_s": 1.5}], want)
    assert differences([], want)
