"""``warning_quality --markdown FILE``: the tables as a Markdown page (``docs/results.md``).

Every table comes with the command that reproduces its figures.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from appliance.evaluation import pooled

COLUMNS = """\
Columns: **runs** scored / made; **coll** a collision scenario (in a pooled row: collision
runs / runs); **lead min/med** lead time of the first level-2 warning on the mover before
contact, min / median over the runs (`MISS n`: n runs without one; target >= 1.5 s);
**lead1 min/med** the same for the first warning of either level (no target; for a standing or
braking lead car the first alert should come >= 2.4 s before contact);
**falseL2** false level-2 warnings (target 0); **L1/min max** level-1 onsets per minute,
worst no-collision run (target <= 1); **detect max** frames from a mover being >= 15 px
tall, visible and moving over the ground to its first matching track, worst run (`MISS`:
never; target <= 10); **TTCerr**, **distErr** median over the runs of each run's median
relative error in the last 3 s before contact (targets 20 % and 15 %); **ghosts/min**
confirmed tracks never on a mover per minute (no target); **targets** `ok`, or the targets
some run failed."""

KITTI_NOTE = """\
Scored by the world's own `score.py` (`../shared/worlds/kitti-street/README.md`), its
figures in these columns: **L1/min** counts every change to level 1 (a level 2 easing to 1
too); **distErr** is the distance definition that fits the run best, from the front bumper,
the camera or the rear axle to the object's footprint *centre* (the appliance reports the
distance to its nearest side: a car's rear read right is 2.25 m short of its centre, 15-25 %
at 9-15 m); **lead1** and **ghosts/min** are not computed (`-`); **targets** are `score.py`'s
(lead >= 1.5 s, no false level 2, detection <= 10 frames, TTC error <= 20 %, rotation
<= 0.05 deg; `rotation` when that failed)."""


def command(args: argparse.Namespace, world: str) -> str:
    parts = ["python -m benchmarks warning_quality", f"--world {world}",
             f"--seeds {args.seeds}", f"--first-seed {args.first_seed}"]
    if args.scenarios:
        parts.append(f"--scenarios {args.scenarios}")
    if args.config:
        parts.append(f"--config {args.config}")
    return " ".join(parts)


def table(rows: Sequence[dict[str, str]]) -> list[str]:
    if not rows:
        return ["(no runs)"]
    heads = list(rows[0])

    def cells(values: Sequence[str]) -> str:
        return "| " + " | ".join(v.replace("|", "\\|") for v in values) + " |"

    return [cells(heads), "|" + "---|" * len(heads)] + [cells([r[h] for h in heads])
                                                         for r in rows]


def write_page(path: Path, args: argparse.Namespace, worlds: Sequence[Any],
               tables: dict[str, list[dict[str, str]]], by_world: list[dict[str, str]],
               digest: str) -> None:
    seeds = f"seeds {args.first_seed}-{args.first_seed + args.seeds - 1}"
    when = datetime.now(UTC).strftime("%Y-%m-%d")
    config = f"configuration `{args.config}`" if args.config else "the default configuration"
    lines = [
        "# Warning quality on simulated drives",
        "",
        (f"Measured {when} with code digest `{digest}` (the `code_digest` in every run's "
         f"`summary.json`) and {config}, {seeds}; the recordings replayed in one batch on Ray "
         "(`appliance.batch`). The commands below regenerate the figures; this page is "
         f"written by `{command(args, args.world)} --markdown FILE`."),
        "",
        COLUMNS,
    ]
    for w in worlds:
        title = "the appliance's simulator" if w.name == "own" else "an independent world"
        lines += ["", f"## {w.name} ({title}): {len(w.scenarios)} scenarios x {seeds}", ""]
        if w.name != "own":
            lines += [KITTI_NOTE, ""]
        lines += [f"`{command(args, w.name)}` (one row alone: `--scenarios NAME`)", ""]
        lines += table(tables[w.name])
        lines += [""] + [f"- {t}" for t in pooled.totals_lines(pooled.totals(w.results))]
        errors = [f"- {r['scenario']}#{r['seed']}: {r['error']}" for r in w.results
                  if "error" in r] + [f"- {e}" for e in w.errors]
        if errors:
            lines += ["", "Failed:"] + errors
    if len(worlds) > 1:
        lines += ["", "## Pooled per world", "", f"`{command(args, 'both')}`", ""]
        lines += table(by_world)
        everything = [r for w in worlds for r in w.results]
        lines += [""] + [f"- {t}" for t in pooled.totals_lines(pooled.totals(everything))]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
