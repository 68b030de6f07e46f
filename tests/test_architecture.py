"""The seams the code is built around, checked on its source.

* Drivers stand alone: ``drivers/`` imports nothing from ``appliance/``.
* Decision never sees an image: the flow it needs is measured in vision (``vision/probes.py``).
* No stage reads another stage's configuration section: vision reads its own sections, decision
  its own (both may read the physical facts ``camera`` and ``mount``); the pipeline step hands
  over what one needs of the other as data.
* The cues are one list: every cue module under ``decision/cues`` is in ``CUES``, once.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
VISION_SECTIONS = {"flow", "detection", "refinement"}
DECISION_SECTIONS = {"probability_map", "clustering", "tracking", "cue", "hidden", "warning"}


def sources(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            out.add(node.module)
    return out


def config_sections(path: Path) -> set[str]:
    """The configuration sections a module reads as ``cfg.<section>`` (any name ending in cfg)."""
    return set(re.findall(r"\bcfg\.([a-z_]+)\b", path.read_text()))


def test_drivers_import_nothing_from_the_appliance() -> None:
    for path in sources("drivers"):
        bad = {m for m in imports(path) if m == "appliance" or m.startswith("appliance.")}
        assert not bad, f"{path.relative_to(ROOT)} imports {bad}"


def test_decision_never_sees_an_image() -> None:
    for path in sources("appliance/decision"):
        text = path.read_text()
        assert "appliance.vision.flow" not in imports(path), path.relative_to(ROOT)
        assert "uint8]" not in text and "calcOpticalFlowPyrLK" not in text, path.relative_to(ROOT)


@pytest.mark.parametrize(("package", "foreign"), [
    ("appliance/vision", DECISION_SECTIONS),
    ("appliance/decision", VISION_SECTIONS),
])
def test_no_stage_reads_another_stages_section(package: str, foreign: set[str]) -> None:
    for path in sources(package):
        read = config_sections(path) & foreign
        assert not read, f"{path.relative_to(ROOT)} reads {sorted(read)}"


def test_every_cue_module_is_in_the_list_once() -> None:
    from appliance.decision.cues import CUES

    names = [c.name for c in CUES]
    assert len(names) == len(set(names))
    modules = {type(c).__module__.rsplit(".", 1)[1] for c in CUES}
    files = {p.stem for p in (ROOT / "appliance/decision/cues").glob("*.py")} - {"__init__", "base"}
    assert modules == files
