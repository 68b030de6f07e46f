"""Pooled warning-quality figures over many runs (batch and warning_quality)."""

from __future__ import annotations

from typing import Any

from appliance.evaluation import pooled


def run(scenario: str, collision: bool, lead: float | None = None, l1_per_min: float = 0.0,
        delay: int | None = 3, ghosts: int | None = 2, ttc: float | None = None,
        false_l2: int = 0, ok: bool = True) -> dict[str, Any]:
    """A result shaped as appliance.evaluation.report's, 30 s long, with one mover."""
    return {
        "scenario": scenario, "collision": collision, "duration_s": 30.0,
        "objects": [{"detection_delay_frames": delay, "tracked_fraction": 0.9}],
        "lead_time_s": lead, "false_level2": false_l2,
        "level1_onsets": round(l1_per_min / 2), "level1_per_min": l1_per_min,
        "level1_on_truth_course": 0, "worst_detection_delay_frames": delay,
        "ttc_rel_error_median": ttc, "distance_rel_error_median": ttc,
        "ghost_tracks": ghosts, "ghost_track_frames": None if ghosts is None else 5 * ghosts,
        "targets": {"lead_time": ok if collision else None, "no_false_level2": false_l2 == 0},
    }


def test_one_row_per_scenario_over_its_seeds() -> None:
    results = [
        run("crossing", True, lead=1.6, ttc=0.10),
        run("crossing", True, lead=2.2, ttc=0.30, delay=12),
        run("braking", True, lead=None, ok=False),
        run("braking", True, lead=2.0),
        run("bend", False, l1_per_min=2.0, delay=None),
        run("bend", False, l1_per_min=0.0, false_l2=1),
        {"scenario": "bend", "error": "frames.csv:3: unreadable line"},
    ]
    rows = {r["scenario"]: r for r in pooled.aggregate(results)}
    assert list(rows) == ["crossing", "braking", "bend"]
    assert rows["crossing"]["lead min/med"] == "1.60/1.90"
    assert rows["crossing"]["TTCerr"] == "20%" and rows["crossing"]["detect max"] == "12"
    assert rows["crossing"]["ghosts/min"] == "4.0"  # 4 ghosts in two 30 s runs
    assert rows["braking"]["lead min/med"] == "MISS 1"
    assert rows["braking"]["targets"] == "FAIL lead_time"
    assert rows["bend"]["runs"] == "2/3" and rows["bend"]["coll"] == "no"
    assert rows["bend"]["L1/min max"] == "2.00" and rows["bend"]["detect max"] == "MISS"
    assert rows["bend"]["falseL2"] == "1"
    assert rows["bend"]["targets"] == "FAIL no_false_level2,errors"


def test_the_first_cautions_lead_is_pooled_only_where_every_run_has_it() -> None:
    own = [dict(run("a", True, lead=1.2), caution_lead_s=2.6),
           dict(run("a", True, lead=1.4), caution_lead_s=2.2),
           dict(run("a", True, lead=1.9), caution_lead_s=None)]
    assert pooled.pooled_row(own[:2])["lead1 min/med"] == "2.20/2.40"
    assert pooled.pooled_row(own)["lead1 min/med"] == "MISS 1"
    # another world's scorer has no first caution: the pooled row does not pretend it has
    assert pooled.pooled_row(own[:2] + [run("k", True, lead=2.0)])["lead1 min/med"] == "-"
    assert pooled.pooled_row([run("b", False)])["lead1 min/med"] == "-"


def test_a_pooled_row_mixes_collision_and_calm_runs() -> None:
    results = [run("a", True, lead=1.8), run("b", False, l1_per_min=1.0),
               run("c", False, ghosts=None)]
    row = pooled.pooled_row(results, "own", label="world")
    assert row["world"] == "own" and row["coll"] == "1/3"
    assert row["lead min/med"] == "1.80/1.80" and row["L1/min max"] == "1.00"
    assert row["ghosts/min"] == "4.0"  # 4 in 1 min: the run without ghost counts left out
    assert pooled.aggregate([{"scenario": "x", "error": "boom"}])[0]["targets"] == "ERROR boom"


def test_totals_count_what_the_rows_summarise() -> None:
    results = [run("a", True, lead=1.4, delay=11), run("a", True, lead=2.0),
               run("b", False, l1_per_min=2.0, false_l2=1), run("c", False, ghosts=None),
               {"scenario": "d", "error": "boom"}]
    t = pooled.totals(results)
    assert (t["runs"], t["runs_failed"], t["collision_runs"]) == (5, 1, 2)
    assert t["collision_runs_lead_ok"] == 1 and t["lead_time_median_s"] == 1.7
    assert t["no_collision_runs_with_false_level2"] == 1 and t["false_level2"] == 1
    assert t["movers"] == 4 and t["movers_confirmed_within_10_frames"] == 3
    assert t["ghost_tracks"] == 6 and t["ghost_minutes"] == 1.5
    lines = pooled.totals_lines(t)
    assert lines[0] == ("collision runs with level 2 >= 1.5 s before contact: 1/2 "
                        "(median lead 1.70 s)")
    assert "6 in 1.5 min (4.00/min)" in lines[-2]
    # a world whose scorer has no ghost tracks gets no ghost line
    assert not any("ghost" in x for x in pooled.totals_lines(
        pooled.totals([run("c", False, ghosts=None)])))
