"""``import-video``: a video file the test writes with OpenCV becomes a recording that replays."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from appliance.cli import main as cli_main
from appliance.config import Config
from appliance.recording import Recording
from drivers.vehicle_signals import SignalKind, VehicleSignalDecoder

FPS = 25.0
N = 30
SIZE = (1280, 720)


@pytest.fixture(scope="module")
def dashcam(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """30 colour frames of 1280x720 at 25 frames/s (MJPG): a textured scene sliding by."""
    rng = np.random.default_rng(3)
    base = cv2.GaussianBlur((rng.random((900, 1600, 3)) * 255).astype(np.uint8), (0, 0), 2.0)
    path = tmp_path_factory.mktemp("video") / "dash.avi"
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), FPS, SIZE)
    assert vw.isOpened()
    for i in range(N):
        vw.write(np.ascontiguousarray(base[60 + 2 * i: 60 + 2 * i + SIZE[1], 100: 100 + SIZE[0]]))
    vw.release()
    return path


def exit_status(argv: list[str]) -> int:
    """The command's exit status, whether argparse (SystemExit) or the command gave it."""
    try:
        return cli_main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def decoded(rec: Recording) -> dict[SignalKind, list[tuple[float, float]]]:
    """(t, SI value) of every speed and yaw-rate frame in can.log, with the recording's [can]."""
    c = rec.meta.can
    dec = VehicleSignalDecoder(c.dbc, speed=c.speed, speed_unit=c.speed_unit,
                               yaw_rate=c.yaw_rate, yaw_rate_unit=c.yaw_rate_unit,
                               yaw_rate_sign=c.yaw_rate_sign)
    out: dict[SignalKind, list[tuple[float, float]]] = {k: [] for k in SignalKind}
    for m in rec.can_messages():
        for v in dec.decode(m.arbitration_id, m.data, m.timestamp, m.is_extended_id):
            out[v.kind].append((v.t, v.value))
    return out


def test_a_dashcam_video_becomes_a_recording_that_replays(
    dashcam: Path, tmp_path: Path, default_config: Config, capsys: pytest.CaptureFixture[str]
) -> None:
    rec_dir = tmp_path / "rec"
    assert cli_main(["import-video", str(dashcam), "--out", str(rec_dir), "--hfov", "90",
                     "--height", "1.25", "--pitch", "3", "--speed", "8.5", "--frames", "5:24",
                     "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "20 frames 640x360 (scaled from 1280x720)" in out and f"replay {rec_dir}" in out
    rec = Recording(rec_dir, defaults=default_config)
    assert rec.validate() > 0
    # frames 5..24 of the video, at their time on the video's clock, scaled to 640 px wide
    assert rec.n_frames == 20
    assert np.allclose(rec.frame_times, np.arange(5, 25) / FPS)
    cam, mount = rec.meta.camera, rec.meta.mount
    assert (cam.width, cam.height) == (640, 360)
    assert cam.fx == pytest.approx(320.0) and cam.fy == pytest.approx(320.0)  # 90 deg over 640 px
    assert (cam.cx, cam.cy) == (pytest.approx(319.5), pytest.approx(179.5))
    assert mount.z_m == 1.25 and mount.pitch_rad == pytest.approx(math.radians(3.0))
    assert mount.x_m == default_config.mount.x_m  # the rest of the mount: the configuration's
    # the video's frame, gray and scaled, stored losslessly
    cap = cv2.VideoCapture(str(dashcam))
    for _ in range(5):
        cap.grab()
    ok, source = cap.read()
    cap.release()
    assert ok
    want = cv2.resize(cv2.cvtColor(source, cv2.COLOR_BGR2GRAY), (640, 360),
                      interpolation=cv2.INTER_AREA)
    assert np.array_equal(next(rec.frames()).image, want)
    # the speed as the configured DBC's frames: 50 Hz each, from 0.1 s before the first frame
    can = decoded(rec)
    speeds, yaws = can[SignalKind.SPEED], can[SignalKind.YAW_RATE]
    assert all(v == pytest.approx(8.5, abs=0.003) for _, v in speeds)  # 0.01 km/h steps
    assert all(v == 0.0 for _, v in yaws)
    assert speeds[0][0] == pytest.approx(5 / FPS - 0.1) and speeds[-1][0] <= 24 / FPS
    assert np.allclose(np.diff([t for t, _ in speeds]), 0.02)
    assert len(speeds) == len(yaws) == round((24 / FPS - (5 / FPS - 0.1)) / 0.02) + 1
    # and replay reads it: every frame processed, vehicle CAN fresh throughout
    run = tmp_path / "run"
    assert cli_main(["replay", str(rec_dir), "--out", str(run), "--no-progress"]) == 0
    summary = json.loads((run / "summary.json").read_text())
    assert summary["frames_processed"] == 20 and summary["can_errors"] == {}
    assert summary["status_changes"] == ["0.200 status ok (faults: none)"]


def test_speed_and_yaw_rate_from_a_csv_and_the_camera_from_a_calibration_file(
    dashcam: Path, tmp_path: Path, default_config: Config, capsys: pytest.CaptureFixture[str]
) -> None:
    csv = tmp_path / "speed.csv"
    # accelerating from 5 to 7 m/s in a left turn; it starts after the video does
    csv.write_text("t,speed_m_s,yaw_rate_rad_s\n0.4,5.0,0.10\n1.4,7.0,0.10\n")
    calib = tmp_path / "camera.yaml"
    fs = cv2.FileStorage(str(calib), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", SIZE[0])
    fs.write("image_height", SIZE[1])
    fs.write("camera_matrix", np.array([[900.0, 0, 650.0], [0, 905.0, 350.0], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.array([[-0.2, 0.05, 0.001, -0.002, 0.0]]))
    fs.release()
    rec_dir = tmp_path / "rec"
    assert cli_main(["import-video", str(dashcam), "--out", str(rec_dir), "--calibration",
                     str(calib), "--height", "1.4", "--pitch", "-1", "--speed-csv", str(csv),
                     "--no-progress"]) == 0
    captured = capsys.readouterr()
    # the first frames have no CAN: one line says they replay degraded
    notes = [line for line in captured.err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "covers t 0.4-1.4 s" in notes[0], captured.err
    rec = Recording(rec_dir, defaults=default_config)
    cam = rec.meta.camera
    assert (cam.fx, cam.fy) == (pytest.approx(450.0), pytest.approx(452.5))
    assert (cam.cx, cam.cy) == (pytest.approx(650.5 / 2 - 0.5), pytest.approx(350.5 / 2 - 0.5))
    assert cam.distortion == pytest.approx((-0.2, 0.05, 0.001, -0.002, 0.0))
    assert rec.meta.mount.pitch_rad == pytest.approx(math.radians(-1.0))
    can = decoded(rec)
    t, v = np.array(can[SignalKind.SPEED]).T
    assert t[0] == pytest.approx(0.4) and t[-1] <= (N - 1) / FPS
    assert np.allclose(v, 5.0 + 2.0 * (t - 0.4), atol=0.003)  # interpolated between the rows
    assert np.allclose([y for _, y in can[SignalKind.YAW_RATE]], 0.10, atol=2e-4)


@pytest.mark.parametrize(
    "args, csv_text, expected",
    [
        (["--hfov", "90", "--height", "1.2", "--pitch", "0"], None, "--speed"),
        (["--hfov", "90", "--height", "1.2", "--pitch", "0", "--speed-csv", "{csv}"],
         "t,speed_m_s\n0,5\n0.5,x\n", "speed.csv:3: expected 2 numbers"),
        (["--hfov", "90", "--height", "1.2", "--pitch", "0", "--speed-csv", "{csv}"],
         "t,speed\n0,5\n", "speed.csv:1: header"),
        (["--hfov", "90", "--height", "1.2", "--pitch", "0", "--speed-csv", "{csv}"],
         "t,speed_m_s\n0,5\n1,300\n", "speed.csv:3: VEHICLE_SPEED.SPEED: 1080 km/h is outside"),
        (["--hfov", "90", "--height", "1.2", "--pitch", "0", "--speed", "-3"], None, "--speed"),
        (["--hfov", "190", "--height", "1.2", "--pitch", "0", "--speed", "5"], None, "--hfov"),
        (["--fx", "700", "--height", "0", "--pitch", "0", "--speed", "5"], None, "--height"),
        (["--fx", "700", "--height", "1.2", "--speed", "5"], None, "--pitch"),
        (["--fx", "700", "--height", "1.2", "--pitch", "0", "--speed", "5", "--frames", "40:"],
         None, "has no frame 40"),
        (["--fx", "700", "--height", "1.2", "--pitch", "0", "--speed", "5", "--frames", "9:3"],
         None, "--frames expects FIRST:LAST"),
        (["--calibration", "{calib}", "--height", "1.2", "--pitch", "0", "--speed", "5"], None,
         "calibrated for 640x480, the video is 1280x720"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    dashcam: Path, tmp_path: Path, args: list[str], csv_text: str | None, expected: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    csv = tmp_path / "speed.csv"
    if csv_text is not None:
        csv.write_text(csv_text)
    calib = tmp_path / "vga.json"
    fs = cv2.FileStorage(str(calib), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", np.eye(3) * 500.0)
    fs.release()
    argv = [a.format(csv=csv, calib=calib) for a in args]
    assert exit_status(["import-video", str(dashcam), "--out", str(tmp_path / "rec"), *argv]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and expected in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "rec").exists()  # nothing written


def test_the_video_and_the_output_directory_are_checked(
    dashcam: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["--fx", "700", "--height", "1.2", "--pitch", "0", "--speed", "5", "--no-progress"]
    not_video = tmp_path / "notes.avi"
    not_video.write_text("not a video")
    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("x")
    cases = [
        ([str(tmp_path / "none.avi"), "--out", str(tmp_path / "r1")], "video not found"),
        ([str(not_video), "--out", str(tmp_path / "r2")], "OpenCV cannot open it"),
        ([str(dashcam), "--out", str(full)], "not an empty directory"),
    ]
    for argv, expected in cases:
        assert cli_main(["import-video", *argv, *base]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and expected in err, err
