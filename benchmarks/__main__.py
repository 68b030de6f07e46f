"""``python -m benchmarks [NAME ...] [OPTIONS]``: run the named benchmarks (all when none is given).

Each benchmark is a module ``benchmarks/<name>.py`` with ``main(argv) -> int`` that
prints its table. They are measurements, not CI gates: the machine is shared, so
they report medians and ratios measured side by side in one run.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path


def available() -> list[str]:
    here = Path(__file__).parent
    return sorted(m.name for m in pkgutil.iter_modules([str(here)]) if not m.name.startswith("_"))


def main(argv: list[str]) -> int:
    # leading words are benchmark names; everything from the first option on goes to them
    split = next((i for i, a in enumerate(argv) if a.startswith("-")), len(argv))
    names, extra = argv[:split], argv[split:]
    if (names and names[0] == "list") or extra[:1] == ["--list"]:
        print("\n".join(available()))
        return 0
    unknown = [n for n in names if n not in available()]
    if unknown:
        print(
            f"unknown benchmark(s): {', '.join(unknown)}; available: {', '.join(available())}",
            file=sys.stderr,
        )
        return 2
    status = 0
    for name in names or available():
        print(f"== {name}", flush=True)
        status |= int(importlib.import_module(f"benchmarks.{name}").main(extra))
    return status


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
