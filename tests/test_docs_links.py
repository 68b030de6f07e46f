"""Every relative link in the README and docs/ reaches a file, and every anchor a heading."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# pages a benchmark writes (`python -m benchmarks warning_quality --markdown docs/results.md`):
# a link to one may precede its first run
GENERATED = {"docs/results.md"}

LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")
HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`|\*|_(?=\W)|(?<=\W)_", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(md: str) -> set[str]:
    out: set[str] = set()
    seen: dict[str, int] = {}
    fenced = False
    for line in md.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        m = None if fenced else HEADING.match(line)
        if m:
            base = slug(m.group(1))
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
    return out


def links(md: str) -> list[str]:
    """Link targets outside code fences and code spans."""
    prose = re.sub(r"```.*?```", "", md, flags=re.DOTALL)
    prose = re.sub(r"`[^`\n]*`", "", prose)
    return LINK.findall(prose)


def doc_pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def broken_links() -> list[str]:
    bad = []
    for page in doc_pages():
        for target in links(page.read_text(encoding="utf-8")):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):   # http:, https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            name = dest.relative_to(ROOT).as_posix() if dest.is_relative_to(ROOT) else str(dest)
            where = f"{page.relative_to(ROOT)}: {target}"
            if not dest.exists():
                if name not in GENERATED:
                    bad.append(f"{where}: no such file")
                continue
            if anchor and dest.suffix == ".md" \
                    and anchor not in anchors(dest.read_text(encoding="utf-8")):
                bad.append(f"{where}: no heading with that anchor")
    return bad


def test_every_relative_link_and_anchor_of_the_docs_resolves() -> None:
    assert len(doc_pages()) >= 4
    assert broken_links() == []


def test_the_checker_finds_a_missing_file_and_a_missing_anchor() -> None:
    md = "# Set up\n\n## Try it: on `your` footage\n\n[a](#set-up) [b](#try-it-on-your-footage)\n"
    assert anchors(md) == {"set-up", "try-it-on-your-footage"}
    assert links(md) == ["#set-up", "#try-it-on-your-footage"]
    assert links("```\n[x](nowhere.md)\n```\n`[y](z.md)` [w](docs/decision.md#scoring-a-run)") \
        == ["docs/decision.md#scoring-a-run"]
    readme = anchors((ROOT / "README.md").read_text(encoding="utf-8"))
    assert "degraded-inputs" in readme and "no-such-section" not in readme
