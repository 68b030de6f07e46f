"""Replay: the pipeline on a recording, outputs per spec, deterministic, bad input exits 2."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import can
import cantools
import cv2
import numpy as np
import pytest

from appliance.config import Config
from appliance.recording import Recording, RecordingWriter, meta_from_config
from appliance.replay import open_recording, replay
from appliance.runtime.outputs import EGOMOTION_HEADER


def write_textured_drive(path: Path, cfg: Config, n: int = 12, speed_kmh: float = 36.0) -> None:
    """A short drive over a static textured plane (image shifts), with real vehicle CAN frames."""
    rng = np.random.default_rng(7)
    base = cv2.GaussianBlur((rng.random((600, 800)) * 255).astype(np.uint8), (0, 0), 1.5)
    db = cantools.database.load_file(cfg.vehicle_can.dbc)
    spd, yaw = db.get_message_by_name("VEHICLE_SPEED"), db.get_message_by_name("YAW_RATE")
    with RecordingWriter(path, meta_from_config(cfg)) as w:
        for i in range(n):
            t = 50.0 + i / 30.0
            w.write_frame(np.ascontiguousarray(base[40 + i : 520 + i, 60:700]), t)
        for k in range(int(n / 30.0 * 50) + 3):
            t = 50.0 - 0.02 + k * 0.02
            w.write_can(
                can.Message(
                    timestamp=t,
                    arbitration_id=spd.frame_id,
                    is_extended_id=False,
                    data=spd.encode({"SPEED": speed_kmh, "COUNTER": k % 16}),
                )
            )
            w.write_can(
                can.Message(
                    timestamp=t + 0.001,
                    arbitration_id=yaw.frame_id,
                    is_extended_id=False,
                    data=yaw.encode({"YAW_RATE": 0.0, "COUNTER": k % 16}),
                )
            )


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory, default_config: Config) -> Path:
    p = tmp_path_factory.mktemp("rec") / "drive"
    write_textured_drive(p, default_config)
    return p


def test_outputs_follow_the_spec(drive: Path, tmp_path: Path, default_config: Config) -> None:
    rec, cfg = open_recording(drive, default_config)
    result = replay(rec, cfg, tmp_path / "out")
    assert result.frames_processed == rec.n_frames == 12
    out = tmp_path / "out"
    rows = [json.loads(x) for x in (out / "tracks.jsonl").read_text().splitlines()]
    assert [r["frame"] for r in rows] == list(range(12))
    assert all(set(r) == {"t", "frame", "tracks"} for r in rows)
    assert rows[3]["t"] == pytest.approx(50.0 + 3 / 30.0)
    with (out / "egomotion.csv").open() as fh:
        ego = list(csv.reader(fh))
    assert ego[0] == EGOMOTION_HEADER and len(ego) == 13
    # the camera moved forward: the refined and prior epipoles are known after the first frame
    assert ego[5][2] != "" and ego[5][7] != ""
    s = json.loads((out / "summary.json").read_text())
    for key in (
        "frames_read",
        "frames_processed",
        "frames_dropped",
        "processing_ms",
        "warnings_issued",
        "version",
        "config_digest",
    ):
        assert key in s
    assert s["frames_processed"] == 12 and s["processing_ms"]["total"]["median"] > 0
    assert (out / "warnings.jsonl").exists()
    # ApplianceStatus heartbeat at 10 Hz on the recording clock, counter rolling, CRC right
    from appliance.runtime.wiring import hmi_codec

    codec = hmi_codec(cfg)
    sent = list(can.LogReader(str(out / "can_out.log")))
    status = [m for m in sent if m.arbitration_id == cfg.hmi_can.status_id]
    assert len(status) >= 3
    decoded = [codec.decode(m.arbitration_id, bytes(m.data)) for m in status]
    assert all(d.crc_ok for d in decoded)
    assert [d.counter for d in decoded] == list(range(len(decoded)))
    gaps = np.diff([m.timestamp for m in status])
    assert np.all(gaps >= 0.099) and np.all(gaps < 0.15)


def test_two_replays_are_identical(drive: Path, tmp_path: Path, default_config: Config) -> None:
    rec, cfg = open_recording(drive, default_config)
    replay(rec, cfg, tmp_path / "a")
    replay(Recording(drive, defaults=default_config), cfg, tmp_path / "b")
    for name in ("tracks.jsonl", "warnings.jsonl", "egomotion.csv", "can_out.log"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "appliance", *args], capture_output=True, text=True, timeout=300
    )


def test_cli_replay_and_corrupt_recording(drive: Path, tmp_path: Path) -> None:
    r = _cli("replay", str(drive), "--out", str(tmp_path / "ok"), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "replayed 12 frames" in r.stdout
    bad = tmp_path / "bad"
    subprocess.run(["cp", "-r", str(drive), str(bad)], check=True)
    lines = (bad / "can.log").read_text().splitlines()
    lines[4] = "(50.07) can0 1A0#XYZ"
    (bad / "can.log").write_text("\n".join(lines) + "\n")
    r = _cli("replay", str(bad), "--out", str(tmp_path / "o2"))
    assert r.returncode == 2
    assert "can.log:5" in r.stderr and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_missing_recording_exits_2(tmp_path: Path) -> None:
    r = _cli("replay", str(tmp_path / "nope"), "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "not a recording directory" in r.stderr


def test_unknown_signal_in_recording_meta_exits_2(drive: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    subprocess.run(["cp", "-r", str(drive), str(bad)], check=True)
    meta = (bad / "meta.toml").read_text().replace("YAW_RATE.YAW_RATE", "YAW_RATE.YAWRATE")
    (bad / "meta.toml").write_text(meta)
    r = _cli("replay", str(bad), "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "YAW_RATE.YAWRATE" in r.stderr and "vehicle.dbc" in r.stderr, (
        r.stderr
    )


def test_annotated_video(drive: Path, tmp_path: Path) -> None:
    r = _cli(
        "replay",
        str(drive),
        "--out",
        str(tmp_path / "o"),
        "--video",
        str(tmp_path / "v.avi"),
        "--no-progress",
    )
    assert r.returncode == 0, r.stderr
    cap = cv2.VideoCapture(str(tmp_path / "v.avi"))
    n = 0
    while cap.read()[0]:
        n += 1
    assert n == 12


def test_out_must_be_new_or_empty_unless_force(
    drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from appliance.cli import main as cli_main

    out = tmp_path / "run"
    base = ["replay", str(drive), "--no-progress", "--out", str(out)]
    assert cli_main(base) == 0
    # what an earlier run left besides the outputs: its evaluation and annotated video
    for name in ("evaluation.json", "timeline.png", "annotated.avi"):
        (out / name).write_text("from the earlier run")
    before = (out / "tracks.jsonl").read_bytes()
    capsys.readouterr()
    assert cli_main(base) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "not empty" in err and "--force" in err, err
    assert (out / "tracks.jsonl").read_bytes() == before  # nothing touched
    assert cli_main([*base, "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["warnings.jsonl", "tracks.jsonl", "egomotion.csv", "can_out.log", "summary.json"]
    )
    # --force never removes what no run writes (here: --out pointed at a recording)
    capsys.readouterr()
    assert cli_main(["replay", str(drive), "--no-progress", "--out", str(drive), "--force"]) == 2
    err = capsys.readouterr().err
    assert "which no run writes" in err and len(err.strip().splitlines()) == 1, err
    assert (drive / "meta.toml").is_file() and (drive / "frames.csv").is_file()
    # a file, or a path under a file
    (tmp_path / "afile").write_text("x")
    for bad in (tmp_path / "afile", tmp_path / "afile" / "run"):
        assert cli_main(["replay", str(drive), "--no-progress", "--out", str(bad)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and str(bad) in err, err
        assert "Traceback" not in err and "internal error" not in err, err


def test_replay_checks_its_config_as_run_does(
    drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from appliance.cli import main as cli_main

    broken = tmp_path / "broken.dbc"
    broken.write_text("BO_ this is not a DBC\n")
    cases = {
        "malformed": (f'[vehicle_can]\ndbc = "{broken}"\n', "malformed DBC"),
        "signal": ('[vehicle_can]\nspeed = "VEHICLE_SPEED.SPED"\n', "VEHICLE_SPEED.SPED"),
    }
    for name, (text, expected) in cases.items():
        cfg = tmp_path / f"{name}.toml"
        cfg.write_text(text)
        out = tmp_path / f"o-{name}"
        for command in (["replay", str(drive)], ["run"]):
            assert cli_main([*command, "--out", str(out), "--config", str(cfg)]) == 2, command
            err = capsys.readouterr().err
            assert len(err.strip().splitlines()) == 1 and expected in err, (name, err)
            assert not out.exists()  # refused before any output was written
    # a valid configuration whose decoding the recording's [can] table replaces: one line says so
    other = tmp_path / "other.toml"
    other.write_text('[vehicle_can]\nspeed_unit = "m/s"\nchannel = "can1"\n')
    assert cli_main(["replay", str(drive), "--no-progress", "--out", str(tmp_path / "o"),
                     "--config", str(other)]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "note:" in line]
    assert len(notes) == 1 and "vehicle_can.speed_unit" in notes[0], err
    assert "channel" not in notes[0] and "meta.toml [can]" in notes[0]
