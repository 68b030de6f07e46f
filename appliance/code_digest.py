"""A digest of the installed appliance code, written into every run's ``summary.json``.

``version`` names a release; this names the exact code that made a run, so a batch that
resumes into an old output directory redoes the runs a code change has made stale.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
from pathlib import Path

# the packages whose files decide a run's outputs; appliance.resources holds the default
# configuration and the DBC files (inside appliance/ when installed, config/ when editable)
PACKAGES = ("appliance", "drivers", "appliance.resources")
SUFFIXES = (".py", ".toml", ".dbc")


@functools.cache
def code_digest() -> str:
    """Short SHA-256 over the packages' source and data files (path and content)."""
    h = hashlib.sha256()
    for name in PACKAGES:
        root = Path(next(iter(importlib.import_module(name).__path__)))
        for path in sorted(root.rglob("*")):
            rel = path.relative_to(root)
            if (
                path.suffix not in SUFFIXES
                or not path.is_file()
                or "__pycache__" in rel.parts
                or (name == "appliance" and rel.parts[0] == "resources")
            ):
                continue
            h.update(f"{name}/{rel.as_posix()}\0".encode())
            h.update(path.read_bytes())
            h.update(b"\0")
    return h.hexdigest()[:16]
