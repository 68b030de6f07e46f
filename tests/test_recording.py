"""Drive recordings: round trip, python-can compatibility, damage named by file and line."""

from __future__ import annotations

import shutil
from pathlib import Path

import can
import numpy as np
import pytest

from appliance.config import Config
from appliance.errors import RecordingError
from appliance.recording import Recording, RecordingWriter, apply_meta, meta_from_config
from tests.conftest import write_small_recording


@pytest.mark.parametrize("video", ["mkv", "avi", "png"])
def test_round_trip_is_identical(tmp_path: Path, default_config: Config, video: str) -> None:
    rec_dir = tmp_path / "rec"
    written = write_small_recording(rec_dir, default_config, video=video)
    rec = Recording(rec_dir)
    assert rec.n_frames == 5
    frames = list(rec.frames())
    assert [f.index for f in frames] == list(range(5))
    for f, img, t in zip(frames, written["frames"], written["times"]):  # type: ignore[call-overload]
        assert f.t == t
        assert f.image.dtype == np.uint8 and f.image.shape == (480, 640)
        np.testing.assert_array_equal(f.image, img)
    msgs = list(rec.can_messages())
    assert len(msgs) == len(written["can"])  # type: ignore[arg-type]
    for a, b in zip(msgs, written["can"]):  # type: ignore[call-overload]
        assert a.arbitration_id == b.arbitration_id and bytes(a.data) == bytes(b.data)
        assert a.timestamp == pytest.approx(b.timestamp, abs=1e-6)
        assert not a.is_extended_id
    ptu = rec.ptu()
    assert ptu is not None
    np.testing.assert_array_equal(
        np.column_stack([ptu.t, ptu.pan, ptu.tilt]), np.array(written["ptu"])
    )
    assert rec.meta.camera.fx == default_config.camera.fx
    assert Path(rec.meta.can.dbc).parent == rec_dir.resolve()  # the DBC travels with the recording
    assert rec.validate() == len(written["can"])  # type: ignore[arg-type]


def test_frames_from_the_middle(tmp_path: Path, default_config: Config) -> None:
    written = write_small_recording(tmp_path / "r", default_config)
    f = next(Recording(tmp_path / "r").frames(start=3))
    assert f.index == 3
    np.testing.assert_array_equal(f.image, written["frames"][3])  # type: ignore[index]


def test_can_log_is_candump_format_readable_by_python_can(
    tmp_path: Path, default_config: Config
) -> None:
    write_small_recording(tmp_path / "r", default_config)
    first = (tmp_path / "r" / "can.log").read_text().splitlines()[0]
    assert first.startswith("(100.000000) can0 1A0#00100000")
    assert len(list(can.LogReader(str(tmp_path / "r" / "can.log")))) > 0


def test_meta_overrides_config(tmp_path: Path, default_config: Config) -> None:
    write_small_recording(tmp_path / "r", default_config)
    text = (tmp_path / "r" / "meta.toml").read_text().replace("fx = 700.0", "fx = 555.0")
    (tmp_path / "r" / "meta.toml").write_text(
        text.replace('speed_unit = "km/h"', 'speed_unit = "m/s"')
    )
    cfg = apply_meta(default_config, Recording(tmp_path / "r").meta)
    assert cfg.camera.fx == 555.0 and cfg.vehicle_can.speed_unit == "m/s"


def _damage(rec: Path, name: str, old: str, new: str) -> None:
    p = rec / name
    p.write_text(p.read_text().replace(old, new, 1))


@pytest.mark.parametrize(
    "name, damage, where",
    [
        ("frames.csv", ("2,", "2,abc_"), "frames.csv:4"),
        ("frames.csv", ("3,", "4,"), "frames.csv:5"),
        ("can.log", ("(100.020000)", "(99.000000)"), "can.log:2"),
        ("can.log", ("(100.040000) can0 1A0#", "(100.040000) can0 1A0#Z"), "can.log:3"),
        ("ptu.csv", ("100.1,", "oops,"), "ptu.csv:4"),
        ("meta.toml", ("fx = 700.0", 'fx = "wide"'), "camera.fx"),
    ],
)
def test_damage_is_named_by_file_and_line(
    tmp_path: Path, default_config: Config, name: str, damage: tuple[str, str], where: str
) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config)
    _damage(rec_dir, name, *damage)
    with pytest.raises(RecordingError) as info:
        Recording(rec_dir).validate()
    assert where in str(info.value), str(info.value)


def test_non_monotonic_frame_time(tmp_path: Path, default_config: Config) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config)
    lines = (rec_dir / "frames.csv").read_text().splitlines()
    lines[3] = "2,99.0"
    (rec_dir / "frames.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"frames.csv:4: non-monotonic"):
        Recording(rec_dir)


@pytest.mark.parametrize("missing", ["meta.toml", "frames.csv", "can.log", "video.mkv"])
def test_missing_files(tmp_path: Path, default_config: Config, missing: str) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config)
    (rec_dir / missing).unlink()
    with pytest.raises(RecordingError) as info:
        Recording(rec_dir)
    assert missing.split(".")[0] in str(info.value)


def test_truncated_recording_is_detected_not_shortened(
    tmp_path: Path, default_config: Config
) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config, n_frames=8)
    # a killed recorder: frames.csv has rows for frames the video never got
    with (rec_dir / "frames.csv").open("a") as fh:
        fh.write("8,200.0\n9,200.1\n")
    with pytest.raises(RecordingError, match="partially written"):
        rec = Recording(rec_dir)
        for _ in rec.frames():
            pass


def test_truncated_png_recording(tmp_path: Path, default_config: Config) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config, video="png")
    (rec_dir / "frames" / "000004.png").unlink()
    with pytest.raises(RecordingError, match="4 PNG files but frames.csv lists 5"):
        Recording(rec_dir)


def test_wrong_frame_size_is_named(tmp_path: Path, default_config: Config) -> None:
    rec_dir = tmp_path / "r"
    write_small_recording(rec_dir, default_config, video="png")
    import cv2

    cv2.imwrite(str(rec_dir / "frames" / "000002.png"), np.zeros((10, 10), np.uint8))
    with pytest.raises(RecordingError, match=r"000002.png: frame 2 is 10x10"):
        list(Recording(rec_dir).frames())


def test_writer_refuses_non_empty_directory(tmp_path: Path, default_config: Config) -> None:
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "file").write_text("keep me")
    with pytest.raises(RecordingError, match="not empty"):
        RecordingWriter(tmp_path / "x", meta_from_config(default_config))
    assert (tmp_path / "x" / "file").read_text() == "keep me"


def test_recording_without_ptu_means_fixed_ptu(tmp_path: Path, default_config: Config) -> None:
    write_small_recording(tmp_path / "r", default_config)
    (tmp_path / "r" / "ptu.csv").unlink()
    assert Recording(tmp_path / "r").ptu() is None


def test_copy_of_recording_elsewhere_still_reads(tmp_path: Path, default_config: Config) -> None:
    write_small_recording(tmp_path / "r", default_config)
    shutil.copytree(tmp_path / "r", tmp_path / "moved")
    shutil.rmtree(tmp_path / "r")
    rec = Recording(tmp_path / "moved")
    assert Path(rec.meta.can.dbc).is_file()
