"""The V4L2 camera driver, run over a real cv2.VideoCapture on a video file (no /dev/video)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from drivers.camera import (
    MAX_BUFFER_AGE_S,
    CameraFrame,
    FramePacing,
    FrameSource,
    V4L2Camera,
    available_sources,
    camera_state,
    capture_time,
    create_source,
    to_gray,
)
from drivers.link import LinkState

WAIT = 5.0
N_FRAMES = 10
W, H = 64, 48


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """10 lossless frames, frame k uniformly 10 k + 5, with a marker pixel."""
    path = tmp_path_factory.mktemp("camera") / "drive.mkv"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"FFV1"), 30.0, (W, H))
    assert writer.isOpened()
    for k in range(N_FRAMES):
        frame = np.full((H, W, 3), 10 * k + 5, np.uint8)
        frame[0, 0] = (255, 0, 0)          # blue in BGR: gray 29 (0.114 * 255)
        writer.write(frame)
    writer.release()
    return path


def camera(video: Path, **kw: object) -> V4L2Camera:
    params: dict[str, object] = dict(width=W, height=H, fps=30.0, reopen_min_s=30.0,
                                     reopen_max_s=30.0,
                                     capture_factory=lambda: cv2.VideoCapture(str(video)))
    params.update(kw)
    return V4L2Camera("/dev/cw-camera", **params)  # type: ignore[arg-type]


def drain(source: FrameSource) -> list[CameraFrame]:
    frames = []
    while (frame := source.read(0.05)) is not None:
        frames.append(frame)
    return frames


def test_frames_are_gray_in_order_and_the_newest_are_kept(video: Path) -> None:
    cam = camera(video, buffer_frames=3)
    with cam:
        assert cam.wait_state(LinkState.LOST, WAIT)      # the file ended: device lost
        frames = drain(cam)
        st = cam.stats
    assert [f.index for f in frames] == [7, 8, 9]           # older ones were overwritten
    for f in frames:
        assert f.image.dtype == np.uint8 and f.image.shape == (H, W)
        assert int(f.image[10, 10]) == 10 * f.index + 5
        assert int(f.image[0, 0]) == round(0.114 * 255)
        assert f.timestamp_source == "retrieval"          # a file has no V4L2 buffer time
    ts = [f.t for f in frames]
    assert all(b > a for a, b in zip(ts, ts[1:]))
    assert (st.frames, st.delivered, st.overwritten) == (N_FRAMES, 3, N_FRAMES - 3)
    assert (st.lost, st.opens, st.size_mismatch, st.late) == (1, 1, 0, 0)
    assert "stream ended" in st.last_error
    assert cam.state is LinkState.STOPPED


def test_a_lost_device_is_reopened_with_backoff(video: Path) -> None:
    cam = camera(video, reopen_min_s=0.02, reopen_max_s=0.05, buffer_frames=64)
    with cam:
        assert cam.wait_stats(lambda st: st.opens >= 2 and st.frames >= 2 * N_FRAMES, WAIT)
    frames = drain(cam)                  # stopped: what was captured is still readable
    values = [int(f.image[10, 10]) for f in frames]
    assert values[:2 * N_FRAMES] == [10 * (k % N_FRAMES) + 5 for k in range(2 * N_FRAMES)]
    assert [f.index for f in frames] == list(range(len(frames)))   # indices run on across reopens
    assert cam.stats.lost >= 1


def test_missing_device_is_reported_not_raised(tmp_path: Path) -> None:
    missing = str(tmp_path / "no-such-video.mkv")
    cam = V4L2Camera(missing, reopen_min_s=0.02, reopen_max_s=0.05,
                     capture_factory=lambda: cv2.VideoCapture(missing))
    with cam:
        assert cam.wait_stats(lambda st: st.open_failures >= 2, WAIT)
        assert cam.state is LinkState.LOST
        assert cam.read(0.01) is None
    assert cam.stats.frames == 0


def test_size_mismatch_is_counted(video: Path) -> None:
    cam = camera(video, width=640, height=480)
    with cam:
        assert cam.wait_state(LinkState.LOST, WAIT)
    assert cam.stats.size_mismatch == N_FRAMES
    assert cam.negotiated["width"] == W and cam.negotiated["height"] == H


def test_capture_time_uses_a_plausible_buffer_time_only() -> None:
    now = 5000.0
    t, from_buffer = capture_time(4999.990 * 1000.0, now)
    assert t == pytest.approx(4999.99) and from_buffer
    assert capture_time(4999.990 * 1000.0, now, "retrieval") == (now, False)
    assert capture_time(33.3, now) == (now, False)                     # a file position
    assert capture_time((now - MAX_BUFFER_AGE_S - 0.1) * 1000.0, now) == (now, False)
    assert capture_time((now + 0.5) * 1000.0, now) == (now, False)     # from the future
    assert capture_time(0.0, now) == (now, False)                      # first V4L2 capture


def test_frame_pacing_counts_late_and_dropped_frames() -> None:
    pacing = FramePacing(fps=30.0, late_factor=1.5)
    period = 1.0 / 30.0
    times = [0.0, period, 2 * period, 5 * period, 6 * period, 6 * period + 1.6 * period]
    results = [pacing.update(t) for t in times]
    assert results == [(False, 0), (False, 0), (False, 0), (True, 2), (False, 0), (True, 1)]
    pacing.reset()
    assert pacing.update(100.0) == (False, 0)


def test_to_gray_accepts_what_opencv_delivers() -> None:
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 2] = 255                                  # red
    assert to_gray(bgr)[0, 0] == round(0.299 * 255)
    assert to_gray(np.full((4, 5), 7, np.uint8)).shape == (4, 5)
    assert to_gray(np.full((4, 5, 1), 7, np.uint8))[0, 0] == 7
    assert to_gray(np.zeros((4, 5, 4), np.uint8)).shape == (4, 5)


def test_registry_builds_sources_by_name(video: Path) -> None:
    assert "v4l2" in available_sources()
    src = create_source("v4l2", device="/dev/video9", width=W, height=H,
                        capture_factory=lambda: cv2.VideoCapture(str(video)))
    assert isinstance(src, V4L2Camera) and src.device == "/dev/video9"
    with pytest.raises(ValueError, match="unknown camera source 'usb'.*v4l2"):
        create_source("usb")
    with pytest.raises(ValueError, match="FOURCC"):
        V4L2Camera(pixel_format="GREY8")


def test_state_goes_stale_when_frames_stop() -> None:
    assert camera_state(LinkState.OK, 10.0, 10.4, 0.5) is LinkState.OK
    assert camera_state(LinkState.OK, 10.0, 10.6, 0.5) is LinkState.STALE
    assert camera_state(LinkState.LOST, 10.0, 20.0, 0.5) is LinkState.LOST
    assert camera_state(LinkState.STARTING, None, 20.0, 0.5) is LinkState.STARTING
