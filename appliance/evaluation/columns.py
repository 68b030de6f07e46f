"""The columns of ``evaluate``'s table and what each means (``evaluate --help``, the README).

Kept apart from the scorer so that the command line can print the legend without loading
it. The definitions behind them are in :mod:`appliance.evaluation.metrics`.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass


@dataclass(frozen=True)
class Column:
    key: str      # key of evaluation.json (or of the table row)
    head: str     # column heading
    spec: str     # format of a number
    meaning: str  # one sentence for the legend


ELIGIBLE = "at least 15 px tall, at least half visible, moving over the ground faster than 0.3 m/s"

COLUMNS = (
    Column("scenario", "scenario", "s", "the scenario named in truth.json"),
    Column("collision", "coll", "",
           "yes: the drive ends in a collision if nobody brakes (truth.json); NO: it does not"),
    Column("worst_detection_delay_frames", "detect(fr)", "",
           "worst detection delay over the movers: frames from a mover's first eligible frame "
           f"({ELIGIBLE}) to the first frame a confirmed track matches it (IoU >= 0.3); 0 when "
           "it was tracked before it became eligible; - when a mover was never eligible or "
           "never detected (target <= 10)"),
    Column("tracked", "tracked", ".0%",
           "the least, over the movers, of the share of its eligible frames in which a "
           "confirmed track matches it"),
    Column("lead_time_s", "lead(s)", ".2f",
           "collision drives: time from the first level-2 warning on the colliding object to "
           "the collision; - when none came before it (target >= 1.5 s)"),
    Column("caution_lead_s", "lead1(s)", ".2f",
           "collision drives: the same for the first warning of either level (level 1 or 2) "
           "on the colliding object; - when none came before it (no target; a standing or "
           "braking lead car's first alert should come >= 2.4 s before contact)"),
    Column("false_level2", "falseL2", "",
           "false level-2 warnings: every level-2 onset of a drive without collision; in a "
           "collision drive, those on no moving object (target 0)"),
    Column("level1_per_min", "L1/min", ".2f",
           "level-1 (caution) onsets from level 0 per minute of recording (target <= 1 in "
           "drives without collision)"),
    Column("ttc_rel_error_median", "TTCerr", ".0%",
           "median |estimated - true| / true time to collision of the colliding object's "
           "track over the last 3 s before the collision (target <= 20 %)"),
    Column("distance_rel_error_median", "distErr", ".0%",
           "the same for the distance, the gap between the car's outline and the object "
           "(target <= 15 %)"),
    Column("ghost_tracks", "ghosts", "",
           "confirmed tracks never on a mover: on static scenery or on nothing (no target)"),
    Column("pass", "targets", "",
           "ok, or FAIL and the targets missed: lead_time, no_false_level2, level1_rate, "
           "detection, ttc_error, distance_error"),
)


def legend(width: int = 92) -> str:
    """The columns as an indented list, one entry per column, wrapped at ``width``."""
    lines = []
    pad = max(len(c.head) for c in COLUMNS) + 2
    for c in COLUMNS:
        lines += textwrap.wrap(
            c.meaning, width, initial_indent=f"  {c.head:<{pad}}", subsequent_indent=" " * (pad + 2)
        )
    return "\n".join(lines)
