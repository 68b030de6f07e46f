"""``collision-warning simulate``: the list, a small run, and exit status 2 with one line."""

from __future__ import annotations

from pathlib import Path

import pytest

from appliance.cli import main
from appliance.recording import Recording
from appliance.sim.scenarios import SCENARIOS


def test_list_names_every_scenario_on_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == list(SCENARIOS)
    assert all(len(line.split()) > 3 for line in lines)
    for name in (
        "pedestrian_crossing_nearside",
        "car_crossing_intersection",
        "cyclist_crossing_intersection",
        "pedestrian_stops_at_kerb",
        "car_crosses_ahead",
        "bend_static",
        "lead_car_driving_away",
        "pedestrian_passes_front",
        "pedestrian_passes_behind",
    ):
        assert name in SCENARIOS


def test_simulate_writes_a_recording_and_says_what_it_wrote(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rec"
    assert (
        main(
            [
                "simulate",
                "pedestrian_crossing_nearside",
                "--out",
                str(out),
                "--seed",
                "3",
                "--duration",
                "0.2",
                "--video",
                "png",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert str(out) in text and "7 frames" in text and "collision_t: 1000.200" in text
    assert len(text.splitlines()) <= 3
    rec = Recording(out)
    assert f"look: fx {rec.meta.camera.fx:.0f} px, camera {rec.meta.mount.z_m:.2f} m" in text
    assert rec.n_frames == 7 and (out / "frames" / "000006.png").is_file()
    truth = rec.truth()
    assert truth is not None and truth["collision_t"] == pytest.approx(1000.2)


@pytest.mark.parametrize(
    "argv,message",
    [
        (["simulate"], "missing SCENARIO"),
        (["simulate", "no_such_drive", "--out", "{tmp}/x"], "unknown scenario 'no_such_drive'"),
        (["simulate", "bend_static"], "missing --out"),
        (["simulate", "bend_static", "--out", "{tmp}/full"], "not empty"),
        (["simulate", "bend_static", "--out", "{tmp}/x", "--duration", "-1"], "--duration"),
        (["simulate", "bend_static", "--out", "{tmp}/x", "--seed", "-3"], "--seed"),
        (["simulate", "bend_static", "--out", "{tmp}/x", "--video", "mp4"], "invalid choice"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert not (tmp_path / "x").exists()
    assert (tmp_path / "full" / "keep.txt").read_text() == "mine"
