"""The demo's preparation: progress while it simulates, and a word when it reuses recordings."""

from __future__ import annotations

from pathlib import Path

import pytest

from appliance import demo


def test_demo_shows_progress_and_says_when_it_reuses_recordings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(demo, "DRIVES", (("bend_static", 0, 1.0),))
    monkeypatch.setattr(demo, "PROGRESS_EVERY_S", 0.2)
    (rec,) = demo.prepare_recordings(tmp_path)
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("simulating 1 drive (1 s of driving"), out
    progress = [line for line in out[1:] if "bend_static" in line]
    assert len(progress) >= 2, out  # a line every PROGRESS_EVERY_S while it runs, and at the end
    assert progress[-1].endswith("bend_static 1.0/1 s"), progress
    assert demo.written_s(rec) == pytest.approx(1.0, abs=0.01)
    assert not any("reusing" in line for line in out)
    # a second demo over the same directory simulates nothing and says so
    assert demo.prepare_recordings(tmp_path) == [rec]
    again = capsys.readouterr().out.splitlines()
    assert len(again) == 1 and again[0].startswith(f"reusing the recordings of an earlier demo in "
                                                   f"{tmp_path}: bend_static"), again
