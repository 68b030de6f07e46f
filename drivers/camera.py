"""Camera frame sources: a small interface, a registry by name, and the V4L2 camera.

:class:`FrameSource` is what the runtime reads frames from: ``open()``,
``read(timeout)`` (the oldest undelivered frame, or None if none arrived in time),
``close()``, ``stats`` and ``state``. Sources register under a name
(:func:`register_source`); this module registers ``"v4l2"``, the appliance registers
its recording- and simulator-backed sources against the same interface.

:class:`V4L2Camera` grabs on its own thread through ``cv2.VideoCapture(device,
cv2.CAP_V4L2)`` with FOURCC, size and rate from its parameters, converts to 8-bit
gray and hands frames over through a small overwrite-oldest buffer, so a slow
consumer never stalls the device (overwritten frames are counted). The capture
factory is injectable: tests run the same code over a real ``cv2.VideoCapture`` on
a video file, whose end is handled like a lost device.

Timestamps (monotonic clock, s): with ``timestamps="auto"`` the V4L2 buffer time is
used, as OpenCV reports it in ``CAP_PROP_POS_MSEC`` after ``grab()`` for the V4L2
backend (the driver's capture time, CLOCK_MONOTONIC for UVC cameras), provided it
is plausible: not in the future and at most ``MAX_BUFFER_AGE_S`` before the time of
retrieval. Otherwise (another clock, a video file's position) the monotonic time
right after ``grab()`` returns is used (``timestamp_source == "retrieval"``) and
the fallback is counted. ``timestamps="retrieval"`` always uses the latter.

Late and dropped frames: a frame arriving more than ``late_factor`` periods after
the previous one is late; ``round(gap / period) - 1`` frames are then counted as
dropped by the device. The period is 1 / the rate the device reports after
configuration (else the requested rate). A lost device (``grab()`` fails, which
OpenCV's V4L2 backend also does after its select timeout) is released, reported as
LOST and reopened with exponential back-off.
"""

from __future__ import annotations

import abc
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.backoff import Backoff
from drivers.link import Counters, LinkState, LinkStatus

log = logging.getLogger(__name__)

MAX_BUFFER_AGE_S = 0.5


@dataclass(frozen=True)
class CameraFrame:
    """One frame: ``index`` counts frames captured since ``open()`` (gaps = overwritten);
    ``t`` monotonic capture time, s; ``image`` 8-bit gray (H, W)."""

    index: int
    t: float
    image: NDArray[np.uint8]
    timestamp_source: str = "retrieval"


@dataclass(frozen=True)
class CameraStats:
    frames: int = 0              # captured
    delivered: int = 0           # returned by read()
    overwritten: int = 0         # captured but replaced before read() (consumer too slow)
    late: int = 0
    dropped: int = 0             # estimated frames the device skipped (gaps in arrival)
    read_failures: int = 0
    lost: int = 0
    opens: int = 0
    open_failures: int = 0
    timestamp_fallbacks: int = 0
    size_mismatch: int = 0
    last_error: str = ""


class FrameSource(abc.ABC):
    """The camera interface the runtime reads from."""

    @abc.abstractmethod
    def open(self) -> None:
        """Start delivering frames; never raises for a missing device (state tells)."""

    @abc.abstractmethod
    def read(self, timeout: float) -> CameraFrame | None:
        """The oldest undelivered frame, waiting up to ``timeout`` s; None if none came."""

    @abc.abstractmethod
    def close(self) -> None:
        """Stop and release the device."""

    @property
    @abc.abstractmethod
    def stats(self) -> CameraStats: ...

    @property
    @abc.abstractmethod
    def state(self) -> LinkState: ...

    def __enter__(self) -> FrameSource:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_REGISTRY: dict[str, Callable[..., FrameSource]] = {}


def register_source(name: str, factory: Callable[..., FrameSource]) -> None:
    """Make ``create_source(name, **params)`` build sources with ``factory(**params)``."""
    _REGISTRY[name] = factory


def available_sources() -> list[str]:
    return sorted(_REGISTRY)


def create_source(name: str, **params: Any) -> FrameSource:
    """A frame source by registered name; ValueError naming the known ones otherwise."""
    if name not in _REGISTRY:
        known = ", ".join(available_sources())
        raise ValueError(f"unknown camera source {name!r} (known: {known})")
    return _REGISTRY[name](**params)


# ------------------------------------------------------------------ pure helpers


def capture_time(pos_msec: float, t_retrieved: float, mode: str = "auto") -> tuple[float, bool]:
    """(capture time s, whether the buffer time was used); see the module docstring."""
    if mode == "auto" and pos_msec > 0.0:
        t_buffer = pos_msec / 1000.0
        if t_retrieved - MAX_BUFFER_AGE_S <= t_buffer <= t_retrieved + 1e-3:
            return t_buffer, True
    return t_retrieved, False


class FramePacing:
    """Late/dropped frame accounting from successive capture times."""

    def __init__(self, fps: float, late_factor: float) -> None:
        self.period = 1.0 / fps
        self.late_factor = late_factor
        self._last: float | None = None

    def reset(self) -> None:
        self._last = None

    def update(self, t: float) -> tuple[bool, int]:
        """(late, estimated frames dropped before this one) for a frame captured at ``t``."""
        last, self._last = self._last, t
        if last is None:
            return False, 0
        gap = t - last
        if gap <= self.late_factor * self.period:
            return False, 0
        return True, max(0, round(gap / self.period) - 1)


def camera_state(published: LinkState, last_frame_t: float | None, now: float,
                 stale_s: float) -> LinkState:
    """The capture thread's state, or STALE when it is OK but the last frame is too old."""
    if published is LinkState.OK and last_frame_t is not None and now - last_frame_t > stale_s:
        return LinkState.STALE
    return published


def to_gray(image: NDArray[Any]) -> NDArray[np.uint8]:
    """8-bit gray (H, W) from what OpenCV delivers (gray, BGR or BGRA)."""
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(1.0, float(image.max())))
    return np.ascontiguousarray(image, dtype=np.uint8)


# ------------------------------------------------------------------ V4L2


CaptureFactory = Callable[[], cv2.VideoCapture]


class V4L2Camera(FrameSource):
    """A V4L2 camera through OpenCV; see the module docstring.

    :param device: device path (``/dev/video0``, the udev link ``/dev/cw-camera``).
    :param width, height: px; ``fps``: frames/s requested; ``pixel_format``: FOURCC.
    :param stale_s: no frame for this long -> state STALE.
    :param buffer_frames: frames held for the consumer (overwrite oldest).
    :param capture_factory: ``() -> cv2.VideoCapture``; default opens ``device`` with
        ``cv2.CAP_V4L2``.
    """

    def __init__(self, device: str = "/dev/video0", *, width: int = 640, height: int = 480,
                 fps: float = 30.0, pixel_format: str = "GREY", reopen_min_s: float = 0.5,
                 reopen_max_s: float = 5.0, late_factor: float = 1.5, stale_s: float = 0.5,
                 timestamps: str = "auto", buffer_frames: int = 2,
                 capture_factory: CaptureFactory | None = None) -> None:
        if len(pixel_format) != 4:
            raise ValueError(f"pixel_format must be a 4-character FOURCC, got {pixel_format!r}")
        if timestamps not in ("auto", "retrieval"):
            raise ValueError(f"timestamps must be 'auto' or 'retrieval', got {timestamps!r}")
        if fps <= 0.0 or late_factor < 1.0 or stale_s <= 0.0 or buffer_frames < 1:
            raise ValueError("fps and stale_s must be > 0, late_factor >= 1, buffer_frames >= 1")
        self.device = device
        self.width, self.height, self.fps = width, height, fps
        self.pixel_format = pixel_format
        self._late_factor = late_factor
        self._stale_s = stale_s
        self._ts_mode = timestamps
        self._factory = capture_factory or (lambda: cv2.VideoCapture(device, cv2.CAP_V4L2))
        self._backoff = Backoff(reopen_min_s, reopen_max_s)
        self._status = LinkStatus(f"camera {device}", log)
        self._counts = Counters()
        self._frames: deque[CameraFrame] = deque(maxlen=buffer_frames)
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_t: float | None = None
        self.negotiated: dict[str, float | str] = {}

    # ---------------------------------------------------------------- FrameSource

    def open(self) -> None:
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="camera", daemon=True)
        self._thread.start()

    def read(self, timeout: float) -> CameraFrame | None:
        with self._cond:
            if not self._cond.wait_for(lambda: len(self._frames) > 0, timeout):
                return None
            frame = self._frames.popleft()
        self._counts.add("delivered")
        return frame

    def close(self, timeout: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        self._status.set(LinkState.STOPPED)

    @property
    def stats(self) -> CameraStats:
        counts, last_error = self._counts.snapshot()
        return CameraStats(**counts, last_error=last_error)

    @property
    def state(self) -> LinkState:
        return self.state_at(time.monotonic())

    def state_at(self, now: float) -> LinkState:
        return camera_state(self._status.state, self._last_t, now, self._stale_s)

    def wait_state(self, state: LinkState, timeout: float) -> bool:
        return self._status.wait_for(state, timeout)

    def wait_stats(self, predicate: Callable[[CameraStats], bool], timeout: float) -> bool:
        return self._counts.wait_for(lambda c: predicate(CameraStats(**c)), timeout)

    # ---------------------------------------------------------------- thread

    def _run(self) -> None:
        index = 0
        while not self._stop.is_set():
            cap = self._factory()
            if not cap.isOpened():
                cap.release()
                self._counts.add("open_failures", error=f"cannot open {self.device}")
                self._status.set(LinkState.LOST, f"cannot open {self.device}")
                self._stop.wait(self._backoff.next_delay())
                continue
            self._counts.add("opens")
            pacing = FramePacing(self._configure(cap), self._late_factor)
            try:
                index = self._capture(cap, pacing, index)
            finally:
                cap.release()
            if not self._stop.is_set():
                self._stop.wait(self._backoff.next_delay())

    def _configure(self, cap: cv2.VideoCapture) -> float:
        """Ask for FOURCC, size and rate (in that order, as V4L2 wants); the rate granted."""
        cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*self.pixel_format))
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.width)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.height)
        cap.set(cv2.CAP_PROP_FPS, self.fps)
        code = int(cap.get(cv2.CAP_PROP_FOURCC))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        self.negotiated = {
            "width": float(cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
            "height": float(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), "fps": fps,
            "fourcc": "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)) if code > 0 else "",
        }
        log.info("camera %s: requested %dx%d %s at %.1f/s, got %s", self.device, self.width,
                 self.height, self.pixel_format, self.fps, self.negotiated)
        return fps if 0.0 < fps < 1000.0 else self.fps

    def _capture(self, cap: cv2.VideoCapture, pacing: FramePacing, index: int) -> int:
        count = self._counts.add
        while not self._stop.is_set():
            grabbed = cap.grab()
            t_retrieved = time.monotonic()
            ok, image = cap.retrieve() if grabbed else (False, None)
            if not ok or image is None:
                count("read_failures")
                count("lost", error=f"{self.device}: no frame (device lost or stream ended)")
                self._status.set(LinkState.LOST, "no frame from the device")
                return index
            t, from_buffer = capture_time(float(cap.get(cv2.CAP_PROP_POS_MSEC)), t_retrieved,
                                          self._ts_mode)
            if not from_buffer and self._ts_mode == "auto":
                count("timestamp_fallbacks")
            gray = to_gray(image)
            if gray.shape != (self.height, self.width):
                count("size_mismatch", error=f"frame {gray.shape[1]}x{gray.shape[0]}, "
                      f"configured {self.width}x{self.height}")
            late, dropped = pacing.update(t)
            if late:
                count("late")
                count("dropped", dropped)
            frame = CameraFrame(index, t, gray, "buffer" if from_buffer else "retrieval")
            index += 1
            with self._cond:
                if len(self._frames) == self._frames.maxlen:
                    count("overwritten")
                self._frames.append(frame)
                self._cond.notify_all()
            self._last_t = t
            count("frames")
            self._backoff.reset()
            self._status.set(LinkState.OK)
        return index


register_source("v4l2", V4L2Camera)
