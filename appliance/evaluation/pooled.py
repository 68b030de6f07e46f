"""Figures pooled over many evaluated runs: the warning-quality table and its totals.

Input: evaluation results as :func:`appliance.evaluation.report.evaluate_run` returns them (one
per run), plus failed runs as ``{"scenario": ..., "error": "..."}``. A result may carry
``None`` for a figure its scorer does not compute (another world's scorer has no ghost
tracks); the table shows ``-`` there and the totals leave it out.

:func:`aggregate` gives one row per group (a scenario over its seeds, or a world over its
scenarios) with the columns of ``python -m benchmarks warning_quality``;
:func:`totals` the pooled figures below the table, :func:`totals_lines` their wording.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from typing import Any

from appliance.evaluation.late import LATE_WINDOW_S, describe, pooled_counts
from appliance.evaluation.metrics import TARGETS

Result = dict[str, Any]

COLUMNS = (
    "runs", "coll", "lead min/med", "lead1 min/med", "falseL2", "L1/min max", "detect max",
    "TTCerr", "distErr", "ghosts/min", "targets",
)


def median(values: Sequence[float]) -> float | None:
    return statistics.median(values) if values else None


def _f(v: float | None, spec: str = ".2f") -> str:
    return "-" if v is None else format(v, spec)


def _min_median(leads: list[float | None]) -> str:
    """min/median of lead times, or ``MISS n`` when n of them are missing."""
    known = [v for v in leads if v is not None]
    if len(known) < len(leads):
        return f"MISS {len(leads) - len(known)}"
    return f"{_f(min(known))}/{_f(median(known))}"


def _row(rs: list[Result], errors: list[Result]) -> dict[str, str]:
    """The table's columns over the runs ``rs`` of one group (``errors``: its failed runs)."""
    if not rs:
        return {"runs": f"0/{len(errors)}", **{c: "-" for c in COLUMNS[1:-1]},
                "targets": "ERROR " + errors[0]["error"]}
    coll = [r for r in rs if r["collision"]]
    calm = [r for r in rs if not r["collision"]]
    delays = [r["worst_detection_delay_frames"] for r in rs if r["objects"]]
    failed = sorted({k for r in rs for k, ok in r["targets"].items() if ok is False})
    l1 = [r["level1_per_min"] for r in calm if r["level1_per_min"] is not None]
    ttc = [r["ttc_rel_error_median"] for r in rs if r["ttc_rel_error_median"] is not None]
    dist = [r["distance_rel_error_median"] for r in rs
            if r["distance_rel_error_median"] is not None]
    ghosts = [r for r in rs if r.get("ghost_tracks") is not None]
    ghost_min = sum(r["duration_s"] for r in ghosts) / 60.0
    lead_txt = _min_median([r["lead_time_s"] for r in coll]) if coll else "-"
    # another world's scorer may not know the first caution: then it is not pooled at all
    has_caution = bool(coll) and all("caution_lead_s" in r for r in coll)
    lead1_txt = _min_median([r["caution_lead_s"] for r in coll]) if has_caution else "-"
    return {
        "runs": f"{len(rs)}/{len(rs) + len(errors)}",
        "coll": "yes" if not calm else "no" if not coll else f"{len(coll)}/{len(rs)}",
        "lead min/med": lead_txt,
        "lead1 min/med": lead1_txt,
        "falseL2": str(sum(r["false_level2"] for r in rs)),
        "L1/min max": _f(max(l1)) if l1 else "-",
        "detect max": "-" if not delays else ("MISS" if None in delays else str(max(delays))),
        "TTCerr": _f(median(ttc), ".0%"),
        "distErr": _f(median(dist), ".0%"),
        "ghosts/min": _f(sum(r["ghost_tracks"] for r in ghosts) / ghost_min, ".1f")
        if ghosts and ghost_min > 0 else "-",
        "targets": "ok" if not failed and not errors else
        "FAIL " + ",".join(failed + (["errors"] if errors else [])),
    }


def aggregate(results: Sequence[Result], group: Callable[[Result], str] | None = None,
              label: str = "scenario") -> list[dict[str, str]]:
    """One row per group (default: per scenario), in order of first appearance."""
    key = group or (lambda r: str(r["scenario"]))
    rows = []
    for name in dict.fromkeys(key(r) for r in results):
        members = [r for r in results if key(r) == name]
        rows.append({label: name, **_row([r for r in members if "error" not in r],
                                          [r for r in members if "error" in r])})
    return rows


def pooled_row(results: Sequence[Result], name: str = "all",
               label: str = "scenario") -> dict[str, str]:
    """The same columns over every run at once."""
    return {label: name, **_row([r for r in results if "error" not in r],
                                [r for r in results if "error" in r])}


def totals(results: Sequence[Result]) -> dict[str, Any]:
    """The pooled figures: warned collision runs, false warnings, cautions, movers, ghosts."""
    ok = [r for r in results if "error" not in r]
    coll = [r for r in ok if r["collision"]]
    calm = [r for r in ok if not r["collision"]]
    leads = [r["lead_time_s"] for r in coll]
    known = [v for v in leads if v is not None]
    movers = [o for r in ok for o in r["objects"]]
    ghosts = [r for r in ok if r.get("ghost_tracks") is not None]
    courses = [r["level1_on_truth_course"] for r in calm
               if r.get("level1_on_truth_course") is not None]
    return {
        "runs": len(results),
        "runs_failed": len(results) - len(ok),
        "collision_runs": len(coll),
        "collision_runs_lead_ok": sum(1 for v in known if v >= 1.5),
        "lead_time_median_s": median(known),
        "false_level2": sum(r["false_level2"] for r in ok),
        "no_collision_runs": len(calm),
        "no_collision_runs_with_false_level2": sum(1 for r in calm if r["false_level2"]),
        "level1_onsets_no_collision": sum(r["level1_onsets"] for r in calm),
        "no_collision_minutes": sum(r["duration_s"] for r in calm) / 60.0,
        "level1_on_truth_course": sum(courses) if len(courses) == len(calm) else None,
        "movers": len(movers),
        "movers_confirmed_within_10_frames": sum(
            1 for o in movers
            if o["detection_delay_frames"] is not None and o["detection_delay_frames"] <= 10),
        "ghost_tracks": sum(r["ghost_tracks"] for r in ghosts) if ghosts else None,
        "ghost_track_frames": sum(r["ghost_track_frames"] for r in ghosts) if ghosts else None,
        "ghost_minutes": sum(r["duration_s"] for r in ghosts) / 60.0,
        "runs_meeting_every_target": sum(
            1 for r in ok if not any(v is False for v in r["targets"].values())),
        "late_runs": sum(1 for r in coll if r.get("late_reasons")),
        "late_counts": dict(pooled_counts(coll)),
    }


def totals_lines(t: dict[str, Any]) -> list[str]:
    """The pooled figures in words, one line each."""
    med = t["lead_time_median_s"]
    lines = [
        (f"collision runs with level 2 >= 1.5 s before contact: "
         f"{t['collision_runs_lead_ok']}/{t['collision_runs']}"
         f" (median lead {'-' if med is None else format(med, '.2f')} s)"),
        (f"false level-2 warnings: {t['false_level2']} (no-collision runs with any: "
         f"{t['no_collision_runs_with_false_level2']}/{t['no_collision_runs']})"),
    ]
    calm_min = t["no_collision_minutes"]
    if calm_min > 0:
        onsets = t["level1_onsets_no_collision"]
        line = (f"level-1 onsets in no-collision runs: {onsets} in {calm_min:.1f} min "
                f"({onsets / calm_min:.2f}/min)")
        if t["level1_on_truth_course"] is not None:
            line += (f"; {t['level1_on_truth_course']} of them raised while the truth course "
                     "met the corridor within the caution horizon")
        lines.append(line)
    lines.append(f"movers confirmed within 10 frames of being >= 15 px tall, visible and moving: "
                 f"{t['movers_confirmed_within_10_frames']}/{t['movers']}")
    if t["ghost_tracks"] is not None and t["ghost_minutes"] > 0:
        lines.append(f"ghost tracks (confirmed, never on a mover): {t['ghost_tracks']} in "
                     f"{t['ghost_minutes']:.1f} min ({t['ghost_tracks'] / t['ghost_minutes']:.2f}"
                     f"/min), {t['ghost_track_frames']} track-frames")
    if t["late_runs"]:
        lo, hi = LATE_WINDOW_S + TARGETS["lead_time_s"], TARGETS["lead_time_s"]
        lines.append(f"the colliding object {lo:g}-{hi:g} s before contact, when a level 2 is in "
                     f"time ({sum(t['late_counts'].values())} frames of {t['late_runs']} runs): "
                     f"{describe(t['late_counts'])}")
    lines.append(f"runs meeting every target: {t['runs_meeting_every_target']}/{t['runs']}")
    return lines


def format_rows(rows: Sequence[dict[str, str]]) -> list[str]:
    """A plain-text table: header, rule, rows (columns as wide as their widest cell)."""
    if not rows:
        return []
    heads = list(rows[0])
    widths = [max(len(h), *(len(r[h]) for r in rows)) for h in heads]
    out = ["  ".join(h.ljust(w) for h, w in zip(heads, widths)).rstrip(),
           "  ".join("-" * w for w in widths)]
    out += ["  ".join(r[h].ljust(w) for h, w in zip(heads, widths)).rstrip() for r in rows]
    return out
