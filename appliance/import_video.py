"""``collision-warning import-video VIDEO --out REC``: your own footage as a drive recording.

A dashcam or phone video has no vehicle bus and no calibration, so the user gives what the
appliance needs and the rest comes from the configuration:

- the camera: ``--fx PX`` (focal length in pixels of the video) or ``--hfov DEG`` (horizontal
  field of view), principal point in the image centre, no distortion; or ``--calibration
  FILE``, an OpenCV FileStorage file (YAML, XML or JSON, as OpenCV's calibration tools write
  it) with ``camera_matrix`` (3x3), optional ``distortion_coefficients`` and optional
  ``image_width``/``image_height`` (which must be the video's);
- the mount: ``--height M`` above the road and ``--pitch DEG`` (positive looks down); where
  the camera sits along the car and the car's size come from ``[mount]``;
- the car's motion: ``--speed M/S`` (constant, straight ahead) or ``--speed-csv FILE`` with
  the header ``t,speed_m_s`` or ``t,speed_m_s,yaw_rate_rad_s`` (t in seconds from the start
  of the video; linear between rows, nothing outside them). It becomes the CAN frames of the
  configured vehicle DBC (``[vehicle_can]``), 50 per second and message, encoded with
  cantools, which the recording's ``[can]`` table then decodes. A video without any speed is
  refused: the appliance cannot judge ego motion it does not know.

Frames wider than ``[camera] width`` (640 px by default, what the pipeline's pixel
parameters are tuned for) are scaled down to it, intrinsics alike; frames are stored gray
(the appliance's camera is monochrome) in FFV1. Frame ``k`` of the video is at ``k / fps``
on the recording clock, fps as the container gives it. ``--frames FIRST:LAST`` (inclusive,
either side may be left out) imports a part. The recording is written with the project's
recording writer, so ``replay`` reads it like any other; ``meta.toml`` says in ``[import]``
where it came from.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.errors import UsageError
from appliance.recording import CanDecoding, RecordingMeta, RecordingWriter
from appliance.runtime.wiring import vehicle_decoder
from appliance.vision.geometry import PinholeCamera
from drivers.vehicle_signals import SignalKind, VehicleSignalEncoder

CAN_PERIOD_S = 0.02  # s, one frame of each speed / yaw-rate message (50 Hz, as the simulator)
CAN_LEAD_S = 0.1  # s of CAN before the first frame, so the first frame has sensor data
SPEED_HEADERS = (["t", "speed_m_s"], ["t", "speed_m_s", "yaw_rate_rad_s"])
MAX_HEIGHT_M = 5.0
MAX_PITCH_DEG = 45.0


@dataclass(frozen=True)
class SpeedTrack:
    """The car's speed (m/s) and yaw rate (rad/s, CCW positive) at times t (s, video clock)."""

    t: NDArray[np.float64]
    speed: NDArray[np.float64]
    yaw_rate: NDArray[np.float64]
    source: str

    def covers(self, t: float) -> bool:
        return bool(self.t[0] <= t <= self.t[-1])

    def at(self, t: float) -> tuple[float, float]:
        return (float(np.interp(t, self.t, self.speed)), float(np.interp(t, self.t, self.yaw_rate)))


def parse_frames(text: str) -> tuple[int, int | None]:
    """``FIRST:LAST`` (inclusive; either may be left out) -> (first, last or None)."""
    first, colon, last = text.partition(":")
    try:
        a = int(first) if first.strip() else 0
        b = int(last) if last.strip() else None
    except ValueError:
        a, b = -1, None
    if not colon or a < 0 or (b is not None and b < a):
        raise argparse.ArgumentTypeError(
            f"--frames expects FIRST:LAST (frame numbers, FIRST <= LAST), got {text!r}"
        )
    return a, b


def constant_speed(speed_m_s: float) -> SpeedTrack:
    if not (math.isfinite(speed_m_s) and speed_m_s >= 0.0):
        raise UsageError(f"--speed must be a speed >= 0 m/s, got {speed_m_s:g}")
    return SpeedTrack(
        np.array([0.0, math.inf]),  # the whole video
        np.array([speed_m_s, speed_m_s]),
        np.zeros(2),
        f"--speed {speed_m_s:g} m/s",
    )


def read_speed_csv(path: Path, encoder: VehicleSignalEncoder) -> SpeedTrack:
    """``t,speed_m_s[,yaw_rate_rad_s]`` rows; every problem names the file and line."""
    try:
        fh = path.open(newline="")
    except OSError as exc:
        raise UsageError(f"--speed-csv {path}: cannot read it: {exc.strerror}") from None
    rows: list[list[float]] = []
    with fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader, [])]
        if header not in SPEED_HEADERS:
            raise UsageError(
                f"{path}:1: header {','.join(header)!r}, expected "
                + " or ".join(repr(",".join(h)) for h in SPEED_HEADERS)
            )
        for row in reader:
            line = reader.line_num
            if not row or all(not c.strip() for c in row):
                continue
            try:
                values = [float(c) for c in row]
            except ValueError:
                values = []
            if len(values) != len(header) or not all(map(math.isfinite, values)):
                raise UsageError(
                    f"{path}:{line}: expected {len(header)} numbers, got {','.join(row)!r}"
                )
            if rows and values[0] <= rows[-1][0]:
                raise UsageError(f"{path}:{line}: t {values[0]:g} is not after {rows[-1][0]:g}")
            try:
                encoder.check(SignalKind.SPEED, values[1])
                if len(values) == 3:
                    encoder.check(SignalKind.YAW_RATE, values[2])
            except ValueError as exc:
                raise UsageError(f"{path}:{line}: {exc}") from None
            rows.append(values)
    if len(rows) < 2:
        raise UsageError(f"{path}: needs at least two rows of t,speed_m_s")
    data = np.array([r + [0.0] * (3 - len(r)) for r in rows])
    return SpeedTrack(data[:, 0], data[:, 1], data[:, 2], f"--speed-csv {path}")


def read_calibration(path: Path) -> tuple[NDArray[np.float64], tuple[float, ...], tuple[int, int] | None]:
    """(camera matrix, distortion, (width, height) or None) of an OpenCV FileStorage file."""
    if not path.is_file():
        raise UsageError(f"--calibration {path}: file not found")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as exc:
        reason = " ".join(str(exc).split())[-200:]
        raise UsageError(f"{path}: not an OpenCV YAML, XML or JSON file ({reason})") from None
    try:
        if not fs.isOpened():
            raise UsageError(f"{path}: not an OpenCV YAML, XML or JSON file")
        k = fs.getNode("camera_matrix").mat()
        if k is None or k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise UsageError(f"{path}: camera_matrix: expected a 3x3 matrix")
        d = fs.getNode("distortion_coefficients").mat()
        dist = () if d is None else tuple(float(x) for x in d.ravel())
        if dist and len(dist) not in (4, 5, 8, 12, 14):
            raise UsageError(
                f"{path}: distortion_coefficients: expected 4, 5, 8, 12 or 14, got {len(dist)}"
            )
        w, h = fs.getNode("image_width"), fs.getNode("image_height")
        size = None if w.empty() or h.empty() else (int(w.real()), int(h.real()))
    finally:
        fs.release()
    if not (k[0, 0] > 0 and k[1, 1] > 0):
        raise UsageError(f"{path}: camera_matrix: fx and fy must be > 0")
    return np.asarray(k, float), dist or (0.0,) * 5, size


def camera_of(args: argparse.Namespace, width: int, height: int) -> PinholeCamera:
    """The camera of the video at its own size, from --fx, --hfov or --calibration."""
    if args.calibration is not None:
        k, dist, size = read_calibration(Path(args.calibration))
        if size is not None and size != (width, height):
            raise UsageError(
                f"{args.calibration}: calibrated for {size[0]}x{size[1]}, "
                f"the video is {width}x{height}"
            )
        return PinholeCamera(width, height, float(k[0, 0]), float(k[1, 1]), float(k[0, 2]),
                             float(k[1, 2]), dist)
    if args.fx is not None:
        if not (math.isfinite(args.fx) and args.fx > 0.0):
            raise UsageError(f"--fx must be a focal length > 0 px, got {args.fx:g}")
        fx = float(args.fx)
    else:
        if not (math.isfinite(args.hfov) and 0.0 < args.hfov < 180.0):
            raise UsageError(f"--hfov must be between 0 and 180 deg, got {args.hfov:g}")
        fx = 0.5 * width / math.tan(math.radians(args.hfov) / 2.0)
    return PinholeCamera(width, height, fx, fx, (width - 1) / 2.0, (height - 1) / 2.0, (0.0,) * 5)


def scaled(cam: PinholeCamera, max_width: int) -> PinholeCamera:
    """``cam`` for frames scaled down to at most ``max_width`` px wide (aspect kept)."""
    if cam.width <= max_width:
        return cam
    w = max_width
    h = max(1, round(cam.height * max_width / cam.width))
    sx, sy = w / cam.width, h / cam.height
    # pixel centres: u' + 0.5 = (u + 0.5) * s
    return PinholeCamera(w, h, cam.fx * sx, cam.fy * sy, (cam.cx + 0.5) * sx - 0.5,
                         (cam.cy + 0.5) * sy - 0.5, tuple(cam.distortion))


def can_frames(track: SpeedTrack, encoder: VehicleSignalEncoder, t_first: float,
               t_last: float) -> list[can.Message]:
    """The vehicle's CAN frames from ``t_first - CAN_LEAD_S`` (not before 0) to ``t_last``,
    where ``track`` has data; the messages of one period spread over it."""
    start = max(0.0, t_first - CAN_LEAD_S, float(track.t[0]))
    end = min(t_last, float(track.t[-1]))
    if end < start:
        return []
    n_msgs = len(encoder.messages)
    out = []
    for k in range(math.floor((end - start) / CAN_PERIOD_S + 1e-9) + 1):
        t = start + k * CAN_PERIOD_S
        for i, (fid, ext, data) in enumerate(encoder.encode(*track.at(t))):
            out.append(can.Message(timestamp=round(t + i * CAN_PERIOD_S / n_msgs, 6),
                                   arbitration_id=fid, is_extended_id=ext, data=data,
                                   channel="can0", is_rx=True))
    return out


def _open_video(path: Path) -> tuple[cv2.VideoCapture, int, int, float, int]:
    if not path.is_file():
        raise UsageError(f"{path}: video not found")
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise UsageError(f"{path}: OpenCV cannot open it (not a video, or an unknown codec)")
    width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
    height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    fps = float(cap.get(cv2.CAP_PROP_FPS))
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    if not 0.0 < fps <= 1000.0:
        cap.release()
        raise UsageError(f"{path}: the container gives no frame rate (got {fps:g})")
    return cap, width, height, fps, count


def _gray(image: NDArray[Any], size: tuple[int, int]) -> NDArray[np.uint8]:
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    if (gray.shape[1], gray.shape[0]) != size:
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(gray, dtype=np.uint8)


def main(args: argparse.Namespace) -> int:
    cfg: Config = args.cfg
    if not (math.isfinite(args.height) and 0.0 < args.height <= MAX_HEIGHT_M):
        raise UsageError(f"--height must be > 0 and <= {MAX_HEIGHT_M:g} m, got {args.height:g}")
    if not (math.isfinite(args.pitch) and abs(args.pitch) <= MAX_PITCH_DEG):
        raise UsageError(f"--pitch must be within +-{MAX_PITCH_DEG:g} deg, got {args.pitch:g}")
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UsageError(f"--out {out}: exists and is not an empty directory")
    encoder = VehicleSignalEncoder(vehicle_decoder(cfg))
    if args.speed_csv is not None:
        track = read_speed_csv(Path(args.speed_csv), encoder)
    else:
        track = constant_speed(args.speed)
        try:
            encoder.check(SignalKind.SPEED, args.speed)
        except ValueError as exc:
            raise UsageError(f"--speed {args.speed:g}: {exc}") from None
    first, last = args.frames if args.frames is not None else (0, None)

    video = Path(args.video)
    cap, width, height, fps, count = _open_video(video)
    try:
        source_cam = camera_of(args, width, height)
        cam = scaled(source_cam, cfg.camera.width)
        for _ in range(first):
            if not cap.grab():
                break
        ok, image = cap.read()
        if not ok or image is None:
            raise UsageError(
                f"--frames {first}:{'' if last is None else last}: {video} has no frame {first} "
                f"(it has {count if count > 0 else 'fewer'} frames)"
            )
        mount = dataclasses.replace(cfg.mount, z_m=float(args.height),
                                    pitch_rad=math.radians(args.pitch))
        v = cfg.vehicle_can
        meta = RecordingMeta(
            camera=cam,
            mount=mount,
            can=CanDecoding(v.dbc, v.speed, v.speed_unit, v.yaw_rate, v.yaw_rate_unit,
                            v.yaw_rate_sign),
            extra={"import": _provenance(args, video, first, width, height, fps, track)},
        )
        bar = _progress(args, count, first, last)
        with RecordingWriter(out, meta, video="mkv", fps=fps) as w:
            index = first
            while True:
                w.write_frame(_gray(image, (cam.width, cam.height)), index / fps)
                if bar is not None:
                    bar.update(1)
                index += 1
                if last is not None and index > last:
                    break
                ok, image = cap.read()
                if not ok or image is None:
                    break
            t_first, t_last = first / fps, (index - 1) / fps
            msgs = can_frames(track, encoder, t_first, t_last)
            for m in msgs:
                w.write_can(m)
            n_frames = w.n_frames
        if bar is not None:
            bar.close()
    finally:
        cap.release()
    _report(out, n_frames, cam, source_cam, t_first, t_last, fps, args, msgs, track, cfg)
    return 0


def _provenance(args: argparse.Namespace, video: Path, first: int, width: int, height: int,
                fps: float, track: SpeedTrack) -> dict[str, Any]:
    camera = (f"--calibration {args.calibration}" if args.calibration is not None
              else f"--fx {args.fx:g}" if args.fx is not None else f"--hfov {args.hfov:g}")
    return {
        "video": str(video.resolve()),
        "first_frame": first,
        "video_width": width,
        "video_height": height,
        "video_fps": fps,
        "camera": camera,
        "speed": track.source,
    }


def _progress(args: argparse.Namespace, count: int, first: int, last: int | None) -> Any:
    if args.no_progress:
        return None
    from tqdm import tqdm

    end = count if last is None else min(last + 1, count) if count > 0 else last + 1
    total = end - first if end and end > first else None
    return tqdm(total=total, unit="frame", file=sys.stderr, desc="import", leave=False)


def _report(out: Path, n_frames: int, cam: PinholeCamera, source: PinholeCamera,
            t_first: float, t_last: float, fps: float, args: argparse.Namespace,
            msgs: list[can.Message], track: SpeedTrack, cfg: Config) -> None:
    size = f"{cam.width}x{cam.height}"
    if (cam.width, cam.height) != (source.width, source.height):
        size += f" (scaled from {source.width}x{source.height})"
    print(f"wrote {out}: {n_frames} frames {size}, t {t_first:.3f}-{t_last:.3f} s at "
          f"{fps:.2f} frames/s, fx {cam.fx:.1f} px, camera {args.height:g} m above the road, "
          f"pitch {args.pitch:g} deg down; {len(msgs)} CAN frames of "
          f"{Path(cfg.vehicle_can.dbc).name} from {track.source}")
    covered = [t for t in (t_first, t_last) if not track.covers(t)]
    if covered:
        print(f"note: {track.source} covers t {track.t[0]:g}-{track.t[-1]:g} s: frames outside "
              "it have no vehicle CAN and replay degraded (vehicle_can_stale)", file=sys.stderr)
    print(f"next: collision-warning replay {out} --out RUN_DIR")
