"""The real-footage benchmark: every level a clip raises counted as an onset, the reasons that
kept its tracks from warning, one row per readable recording and an error row for a bad one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from appliance.config import Config
from benchmarks import real_footage
from conftest import write_small_recording


def _jsonl(path: Path, rows: list[dict[str, object]]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_onsets_count_each_rise_of_the_level(tmp_path: Path) -> None:
    levels = [1, 2, 1, 0, 2, 0, 1]
    path = _jsonl(tmp_path / "warnings.jsonl", [{"t": float(i), "frame": i, "level": lv}
                                                 for i, lv in enumerate(levels)])
    # level 1 from 0: at 0, 4 (straight to 2) and 6; level 2: at 1 (from 1) and 4 (from 0)
    assert real_footage.onsets(path) == (3, 2)
    assert real_footage.onsets(_jsonl(tmp_path / "none.jsonl", [])) == (0, 0)


def test_census_counts_track_frames_per_reason_without_figures(tmp_path: Path) -> None:
    rows = [{"t": 10.0, "frame": 0, "tracks": [
                {"id": 3, "reason": "probability 0.41 below 0.60"},
                {"id": 4, "reason": "not moving over ground"}]},
            {"t": 10.1, "frame": 1, "tracks": [
                {"id": 3, "reason": "probability 0.52 below 0.60"}]},
            {"t": 10.2, "frame": 2, "tracks": []}]
    frames, seconds, n_tracks, reasons = real_footage.census(_jsonl(tmp_path / "t.jsonl", rows))
    assert (frames, n_tracks) == (3, 2)
    assert seconds == pytest.approx(0.3)
    assert reasons == {"probability # below #": 2, "not moving over ground": 1}


def test_each_recording_gets_a_row_and_a_bad_one_an_error(
        tmp_path: Path, default_config: Config, capsys: pytest.CaptureFixture[str]) -> None:
    write_small_recording(tmp_path / "clip_a", default_config, n_frames=4)
    bad = tmp_path / "clip_b"
    bad.mkdir()
    (bad / "meta.toml").write_text("[camera\n")
    (tmp_path / "notes").mkdir()      # not a recording: no meta.toml

    status = real_footage.main(["--recordings", str(tmp_path)])

    out = capsys.readouterr().out
    assert status == 1
    assert "2 recordings in" in out
    row = next(line for line in out.splitlines() if line.startswith("clip_a"))
    assert row.split()[2] == "4"                       # frames replayed
    assert "clip_b" in out and "error:" in out and "meta.toml" in out
    assert "level-2 onsets 0" in out


def test_no_recordings_is_a_usage_error(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert real_footage.main(["--recordings", str(tmp_path)]) == 2
    assert "no drive recordings" in capsys.readouterr().err
