"""Read and validate a drive recording (spec: "Drive recording").

Frames are streamed one at a time from ``video.mkv``/``video.avi`` or
``frames/NNNNNN.png`` (a 10-minute drive is never loaded whole); ``can.log`` is
streamed through python-can's ``CanutilsLogReader``. Every inconsistency raises
:class:`~appliance.errors.RecordingError` naming the file and, where there is
one, the line.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import can
import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.errors import RecordingError
from appliance.messages import Frame
from appliance.recording.meta import RecordingMeta, read_meta

VIDEO_NAMES = ("video.mkv", "video.avi")


@dataclass(frozen=True)
class PtuTrack:
    """Measured PTU positions: times (s) and pan/tilt (rad), shape (M,)."""

    t: NDArray[np.float64]
    pan: NDArray[np.float64]
    tilt: NDArray[np.float64]


class _CountingLines:
    """A text file that remembers the number of the line last handed out."""

    def __init__(self, fh: TextIO) -> None:
        self._fh = fh
        self.line = 0

    def __iter__(self) -> Iterator[str]:
        for text in self._fh:
            self.line += 1
            yield text

    def close(self) -> None:
        self._fh.close()


def _read_csv(path: Path, header: list[str], required: bool = True) -> list[tuple[int, list[str]]]:
    """Rows of a small CSV with an exact header, each with its line number."""
    try:
        fh = path.open(newline="")
    except FileNotFoundError:
        if required:
            raise RecordingError(path, "missing") from None
        return []
    with fh:
        reader = csv.reader(fh)
        try:
            first = next(reader)
        except StopIteration:
            raise RecordingError(
                path, f"empty; expected the header {','.join(header)}", 1
            ) from None
        if [h.strip() for h in first] != header:
            raise RecordingError(
                path, f"header {','.join(first)!r}, expected {','.join(header)!r}", 1
            )
        rows = []
        for row in reader:
            if not row or all(not c.strip() for c in row):
                continue
            rows.append((reader.line_num, row))
        return rows


def _floats(path: Path, line: int, row: list[str], n: int) -> list[float]:
    if len(row) != n:
        raise RecordingError(path, f"expected {n} columns, found {len(row)}", line)
    try:
        values = [float(c) for c in row]
    except ValueError:
        raise RecordingError(path, f"unreadable line {','.join(row)!r}", line) from None
    if not all(math.isfinite(v) for v in values):
        raise RecordingError(path, f"non-finite value in {','.join(row)!r}", line)
    return values


class Recording:
    """A drive recording directory, validated on open.

    ``defaults`` supplies what a recording may leave out (its ``[can]`` table,
    distortion); without it those keys are required.
    """

    def __init__(self, path: str | Path, defaults: Config | None = None) -> None:
        self.path = Path(path)
        if not self.path.is_dir():
            raise RecordingError(
                self.path, "not a recording directory (not found or not a directory)"
            )
        self.meta: RecordingMeta = read_meta(self.path / "meta.toml", defaults)
        self.frame_times = self._read_frame_times()
        self.video_path: Path | None = None
        self.frames_dir: Path | None = None
        for name in VIDEO_NAMES:
            if (self.path / name).is_file():
                self.video_path = self.path / name
                break
        if self.video_path is None:
            if (self.path / "frames").is_dir():
                self.frames_dir = self.path / "frames"
            else:
                raise RecordingError(self.path, "no video.mkv, video.avi or frames/ directory")
        self._check_frame_count()
        if not (self.path / "can.log").is_file():
            raise RecordingError(self.path / "can.log", "missing")

    # ------------------------------------------------------------ frames

    @property
    def n_frames(self) -> int:
        return int(self.frame_times.shape[0])

    def _read_frame_times(self) -> NDArray[np.float64]:
        path = self.path / "frames.csv"
        rows = _read_csv(path, ["frame", "t"])
        times = np.empty(len(rows))
        for i, (line, row) in enumerate(rows):
            idx, t = _floats(path, line, row, 2)
            if idx != i:
                raise RecordingError(
                    path, f"frame index {row[0]} out of sequence, expected {i}", line
                )
            if i and t <= times[i - 1]:
                raise RecordingError(path, f"non-monotonic time {t!r} after {times[i - 1]!r}", line)
            times[i] = t
        if len(rows) == 0:
            raise RecordingError(path, "no frames")
        return times

    def _check_frame_count(self) -> None:
        if self.frames_dir is not None:
            pngs = sorted(self.frames_dir.glob("*.png"))
            if len(pngs) != self.n_frames:
                raise RecordingError(
                    self.frames_dir,
                    f"{len(pngs)} PNG files but frames.csv lists {self.n_frames} frames",
                )
            return
        assert self.video_path is not None
        cap = cv2.VideoCapture(str(self.video_path))
        try:
            if not cap.isOpened():
                raise RecordingError(
                    self.video_path, "cannot be opened (unreadable or truncated video)"
                )
            count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            cap.release()
        if count > 0 and count != self.n_frames:
            raise RecordingError(
                self.video_path,
                f"holds {count} frames but frames.csv lists {self.n_frames} "
                "(a partially written recording?)",
            )

    def _check_image(
        self, image: NDArray[Any] | None, where: Path, index: int
    ) -> NDArray[np.uint8]:
        if image is None:
            raise RecordingError(where, f"frame {index} unreadable")
        if image.dtype != np.uint8:
            raise RecordingError(
                where, f"frame {index} is {image.dtype}, expected 8-bit gray or BGR"
            )
        if image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        h, w = image.shape[:2]
        cam = self.meta.camera
        if (w, h) != (cam.width, cam.height):
            raise RecordingError(
                where, f"frame {index} is {w}x{h}, meta.toml says {cam.width}x{cam.height}"
            )
        return np.ascontiguousarray(image, dtype=np.uint8)

    def frames(self, start: int = 0) -> Iterator[Frame]:
        """Stream the frames as 8-bit gray ``Frame`` objects, from index ``start``."""
        times = self.frame_times
        if self.frames_dir is not None:
            for i in range(start, self.n_frames):
                p = self.frames_dir / f"{i:06d}.png"
                if not p.is_file():
                    raise RecordingError(p, f"missing (frames.csv lists frame {i})")
                img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
                yield Frame(i, float(times[i]), self._check_image(img, p, i))
            return
        assert self.video_path is not None
        cap = cv2.VideoCapture(str(self.video_path))
        if not cap.isOpened():
            raise RecordingError(self.video_path, "cannot be opened")
        try:
            if start:
                cap.set(cv2.CAP_PROP_POS_FRAMES, start)
            i = start
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                if i >= self.n_frames:
                    raise RecordingError(
                        self.video_path,
                        f"has more frames than the {self.n_frames} frames.csv lists",
                    )
                yield Frame(i, float(times[i]), self._check_image(img, self.video_path, i))
                i += 1
            if i < self.n_frames:
                raise RecordingError(
                    self.video_path,
                    f"ended after {i} frames but frames.csv lists {self.n_frames} "
                    "(a partially written recording?)",
                )
        finally:
            cap.release()

    # ------------------------------------------------------------ CAN, PTU, truth

    def can_messages(self) -> Iterator[can.Message]:
        """Stream ``can.log`` through python-can's reader; errors name the line."""
        path = self.path / "can.log"
        lines = _CountingLines(path.open("r", encoding="ascii", errors="replace"))
        reader = can.CanutilsLogReader(lines)  # type: ignore[arg-type]
        last = -math.inf
        try:
            it = iter(reader)
            while True:
                try:
                    msg = next(it)
                except StopIteration:
                    break
                except (ValueError, IndexError) as exc:
                    raise RecordingError(
                        path, f"unreadable CAN frame ({exc})", lines.line
                    ) from None
                if not math.isfinite(msg.timestamp):
                    raise RecordingError(path, "non-finite timestamp", lines.line)
                if msg.timestamp < last:
                    raise RecordingError(
                        path,
                        f"non-monotonic timestamp {msg.timestamp:.6f} after {last:.6f}",
                        lines.line,
                    )
                last = msg.timestamp
                yield msg
        finally:
            lines.close()

    def ptu(self) -> PtuTrack | None:
        """The measured PTU positions, or None when ``ptu.csv`` is absent (PTU fixed at zero)."""
        path = self.path / "ptu.csv"
        if not path.is_file():
            return None
        rows = _read_csv(path, ["t", "pan_rad", "tilt_rad"])
        data = np.empty((len(rows), 3))
        for i, (line, row) in enumerate(rows):
            data[i] = _floats(path, line, row, 3)
            if i and data[i, 0] < data[i - 1, 0]:
                raise RecordingError(path, f"non-monotonic time {data[i, 0]!r}", line)
        return PtuTrack(data[:, 0].copy(), data[:, 1].copy(), data[:, 2].copy())

    def truth(self) -> dict[str, Any] | None:
        """``truth.json`` (simulator recordings only). The pipeline never calls this."""
        path = self.path / "truth.json"
        if not path.is_file():
            return None
        try:
            with path.open() as fh:
                data = json.load(fh)
        except json.JSONDecodeError as exc:
            raise RecordingError(path, f"invalid JSON: {exc.msg}", exc.lineno) from None
        if not isinstance(data, dict):
            raise RecordingError(path, "expected a JSON object")
        return data

    def validate(self) -> int:
        """Read every CAN line and PTU row once (frames are checked as they stream).

        Returns the number of CAN frames. Used by ``replay`` before it starts, so a
        corrupt log is reported up front rather than half way through.
        """
        n = sum(1 for _ in self.can_messages())
        self.ptu()
        return n
