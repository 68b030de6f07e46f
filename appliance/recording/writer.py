"""Write a drive recording (spec: "Drive recording").

Used by the simulator, by ``run --record`` and by the tests, so every writer of
recordings produces exactly the same format. Rows are flushed as they are
written, so a recording cut short by a crash is still readable up to the point
where it stopped, and the reader detects that it was cut short.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path
from types import TracebackType
from typing import Any

import can
import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.errors import RecordingError
from appliance.recording.meta import RecordingMeta, write_meta

VIDEO_FORMATS = {"mkv": ("video.mkv", "FFV1"), "avi": ("video.avi", "FFV1"), "png": (None, None)}


class RecordingWriter:
    """Writes a recording directory.

    :param path: directory to create (must be empty or absent).
    :param meta: camera, mount and CAN decoding; the DBC is copied into the recording.
    :param video: ``"mkv"`` (FFV1, lossless, default), ``"avi"`` (FFV1) or ``"png"`` (frames/).
    :param fps: nominal frame rate stored in the video container.
    """

    def __init__(
        self, path: str | Path, meta: RecordingMeta, video: str = "mkv", fps: float = 30.0
    ) -> None:
        if video not in VIDEO_FORMATS:
            raise ValueError(f"video must be one of {', '.join(VIDEO_FORMATS)}")
        self.path = Path(path)
        if self.path.exists() and any(self.path.iterdir()):
            raise RecordingError(self.path, "output directory exists and is not empty")
        self.path.mkdir(parents=True, exist_ok=True)
        self.meta = meta
        self.video = video
        self.fps = fps
        dbc = Path(meta.can.dbc)
        dbc_name = None
        if dbc.is_file():
            dbc_name = dbc.name
            shutil.copyfile(dbc, self.path / dbc_name)
        write_meta(self.path / "meta.toml", meta, dbc_name)
        self._frames_fh = (self.path / "frames.csv").open("w", newline="")
        self._frames = csv.writer(self._frames_fh, lineterminator="\n")
        self._frames.writerow(["frame", "t"])
        self._can_log = can.CanutilsLogWriter(str(self.path / "can.log"))
        self._ptu_fh: Any = None
        self._ptu: Any = None
        self._vw: cv2.VideoWriter | None = None
        self.n_frames = 0
        self.n_can = 0
        self.video_bytes = 0
        self._last_t: float | None = None
        if video == "png":
            (self.path / "frames").mkdir()

    def write_frame(self, image: NDArray[np.uint8], t: float) -> int:
        """Append one frame (gray or BGR, 8 bit) captured at ``t``; returns its index."""
        if self._last_t is not None and t <= self._last_t:
            raise ValueError(f"frame time {t!r} not after the previous {self._last_t!r}")
        h, w = image.shape[:2]
        if (w, h) != (self.meta.camera.width, self.meta.camera.height):
            raise ValueError(
                f"frame is {w}x{h}, meta says {self.meta.camera.width}x{self.meta.camera.height}"
            )
        index = self.n_frames
        if self.video == "png":
            p = self.path / "frames" / f"{index:06d}.png"
            if not cv2.imwrite(str(p), image):
                raise RecordingError(p, "could not be written")
            self.video_bytes += p.stat().st_size
        else:
            if self._vw is None:
                name, fourcc = VIDEO_FORMATS[self.video]
                assert name is not None and fourcc is not None
                self._vw = cv2.VideoWriter(
                    str(self.path / name),
                    cv2.VideoWriter.fourcc(*fourcc),
                    self.fps,
                    (w, h),
                    isColor=image.ndim == 3,
                )
                if not self._vw.isOpened():
                    raise RecordingError(self.path / name, f"OpenCV cannot write {fourcc} video")
            self._vw.write(image)
            self.video_bytes += (
                image.nbytes // 3
            )  # estimate; FFV1 is about 1/3 of raw on camera images
        self._frames.writerow([index, repr(float(t))])
        self._frames_fh.flush()
        self._last_t = t
        self.n_frames += 1
        return index

    @property
    def last_t(self) -> float | None:
        """Capture time of the last frame written (None before the first)."""
        return self._last_t

    def write_can(self, msg: can.Message) -> None:
        """Append one CAN frame (its ``timestamp`` on the recording clock) to ``can.log``."""
        self._can_log.on_message_received(msg)
        self.n_can += 1

    def write_ptu(self, t: float, pan_rad: float, tilt_rad: float) -> None:
        """Append one measured PTU position to ``ptu.csv`` (created on first use)."""
        if self._ptu is None:
            self._ptu_fh = (self.path / "ptu.csv").open("w", newline="")
            self._ptu = csv.writer(self._ptu_fh, lineterminator="\n")
            self._ptu.writerow(["t", "pan_rad", "tilt_rad"])
        self._ptu.writerow([repr(float(t)), repr(float(pan_rad)), repr(float(tilt_rad))])

    def write_truth(self, truth: dict[str, Any]) -> None:
        """Write ``truth.json`` (simulators only)."""
        with (self.path / "truth.json").open("w") as fh:
            json.dump(truth, fh, separators=(",", ":"))

    def flush(self) -> None:
        self._frames_fh.flush()
        self._can_log.file.flush()
        if self._ptu_fh is not None:
            self._ptu_fh.flush()

    def close(self) -> None:
        if self._vw is not None:
            self._vw.release()
            self._vw = None
        self._frames_fh.close()
        self._can_log.stop()
        if self._ptu_fh is not None:
            self._ptu_fh.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
