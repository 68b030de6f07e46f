"""What kept a level 2 from being in time (``appliance/evaluation/late.py``): the colliding
object's frames 3.5-1.5 s before contact, each by the furthest state of a track on it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from appliance.cli import main as cli_main
from appliance.config import Config
from appliance.decision.warnings import ONLY_MAY_STAND
from appliance.evaluation import pooled
from appliance.evaluation.late import describe, kind, late_reasons
from appliance.evaluation.report import evaluate_run, late_of_run
from appliance.evaluation.runfiles import TrackRow, TruthObject
from test_evaluate import CT, FPS, N, T0, mover_box, write_recording, write_run


def reasons_run(run: Path) -> Path:
    """The mover (collision 2.5 s into the recording, frame 75) with no track up to frame 9;
    one held back by its evidence over frames 10-19 (and a warning elsewhere, on the static
    scene); two on it over frames 20-39, the further one only waiting for its TTC; then warned.
    The window 3.5-1.5 s before contact holds frames 0-30 (the recording starts 2.5 s before)."""
    tracks: list[dict[str, object]] = []

    def on_mover(f: int, tid: int, reason: str) -> None:
        tracks.append({"frame": f, "id": tid, "bbox": mover_box(f), "probability": 0.4,
                       "flow": [0.0, 0.0], "ttc_s": None, "distance_m": None, "reason": reason})

    for f in range(10, 20):
        on_mover(f, 5, "probability 0.40 below 0.50")
        tracks.append({"frame": f, "id": 9, "bbox": [250, 20, 280, 60], "probability": 0.9,
                       "flow": [0.0, 0.0], "ttc_s": 1.0, "distance_m": 8.0, "reason": "warning"})
    for f in range(20, 40):
        on_mover(f, 5, "not moving over ground")
        on_mover(f, 6, "ttc 2.6 s above 2.0 s")
    for f in range(40, N):
        on_mover(f, 6, "warning")
    return write_run(run, tracks, [])


def test_the_frames_before_the_target_lead_are_told_by_the_furthest_track(
        tmp_path: Path, default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = reasons_run(tmp_path / "run")
    r = evaluate_run(rec, run)
    late = r["late_reasons"]
    assert late["window_s"] == [3.5, 1.5]
    # frames 0-30: 2.5 s (the recording's start) to 1.5 s before contact
    assert late["counts"] == {"no track": 10, "probability": 10, "ttc above threshold": 11}
    assert late["frames"] == 31
    # the same for a run scored by another world's scorer
    assert late_of_run(rec, run) == late


def test_evaluate_prints_the_breakdown(tmp_path: Path, default_config: Config,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = reasons_run(tmp_path / "run")
    assert cli_main(["evaluate", str(rec), str(run)]) == 0
    out = capsys.readouterr().out
    assert ("3.5-1.5 s before contact (a level 2 then is in time), 31 frames: "
            "ttc above threshold 35 %, probability 32 %, no track 32 %") in out


def test_a_drive_without_a_collision_has_no_breakdown(tmp_path: Path,
                                                     default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config, collision=False)
    run = reasons_run(tmp_path / "run")
    assert evaluate_run(rec, run)["late_reasons"] is None


def test_reasons_are_classed_by_the_check_they_fail() -> None:
    assert kind("warning, held: ttc 5.0 s above 2.1 s") == "warning"
    assert kind("caution indicated 2 of 3 frames") == "caution"
    assert kind("caution, track 3 warned") == "caution"
    assert kind(f"caution: {ONLY_MAY_STAND}") == "caution, only may stand"
    assert kind("ttc 3.4 s above 3.1 s") == "ttc above threshold"
    assert kind("path misses corridor by 0.9 m, hidden") == "path misses corridor"
    assert kind("path stays 14.0 m ahead in the corridor") == "path stays ahead"
    assert kind("probability 0.42 below 0.50") == "probability"
    assert kind("box 0.12 m tall, below 0.30 m") == "box too low"
    assert kind("standing: not yet seen coming nearer") == "standing, not closing"
    assert kind("stands at the roadside, which comes nearer beside it (a bend)") == "roadside"
    assert kind("not moving over ground") == "not moving over ground"
    assert kind(None) == "other" and kind("something new") == "other"


def test_a_hidden_object_without_a_track_is_hidden_not_missed() -> None:
    frames = np.arange(N, dtype=np.int64)
    boxes = np.array([mover_box(int(f)) for f in frames])
    visible = np.where(frames < 15, 0.2, 1.0)
    o = TruthObject(id=1, cls="child", moving=True, frames=frames, bbox=boxes, visible=visible,
                    pos=np.zeros((N, 2)))
    times = T0 + frames / FPS
    tracks = [TrackRow(frame=int(f), t=float(times[f]), id=3, bbox=tuple(mover_box(int(f))),
                       ttc_s=None, distance_m=None, reason="not moving over ground")
              for f in range(25, N)]
    late = late_reasons(o, CT, tracks, times, (320, 240))
    assert late["counts"] == {"hidden": 15, "no track": 10, "not moving over ground": 6}


def test_the_pooled_figures_sum_the_frames_of_the_collision_runs() -> None:
    def result(collision: bool, counts: dict[str, int] | None) -> dict[str, object]:
        return {"collision": collision, "lead_time_s": None, "false_level2": 0,
                "level1_onsets": 0, "duration_s": 8.0, "objects": [], "targets": {},
                "late_reasons": None if counts is None else {
                    "window_s": [3.5, 1.5], "frames": sum(counts.values()), "counts": counts}}

    t = pooled.totals([result(True, {"no track": 30, "warning": 10}),
                       result(True, {"no track": 10, "probability": 30}),
                       result(True, None), result(False, None)])
    assert t["late_runs"] == 2
    assert t["late_counts"] == {"no track": 40, "warning": 10, "probability": 30}
    line = [x for x in pooled.totals_lines(t) if x.startswith("the colliding object")]
    assert line == ["the colliding object 3.5-1.5 s before contact, when a level 2 is in time "
                    "(80 frames of 2 runs): no track 50 %, probability 38 %, warning 12 %"]
    assert describe({}) == "no frames"
