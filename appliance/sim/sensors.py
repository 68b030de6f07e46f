"""Simulated sensors on the recording clock: camera frame times, vehicle CAN, PTU positions.

* Frames at 30 frames/s with a little capture jitter (first frame exactly at ``t0``).
* ``VEHICLE_SPEED`` and ``YAW_RATE`` of ``config/vehicle.dbc`` at 50 Hz each,
  encoded with cantools, with white noise and a small bias (a wheel-radius scale
  error on the speed, a gyro offset on the yaw rate) and rolling 4-bit counters.
* PTU positions at 20 Hz, quantised to the PTU-D46 step (185.1428 arcsec).

CAN and PTU start ``lead_s`` before the first frame, so the first frame already
has sensor data.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import can
import cantools
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

FPS = 30.0
CAN_PERIOD_S = 0.02
PTU_PERIOD_S = 0.05
PTU_STEP_RAD = 185.1428 / 3600.0 * np.pi / 180.0


def frame_times(
    rng: np.random.Generator, n: int, fps: float = FPS, jitter_s: float = 0.0005
) -> FloatArray:
    """Offsets (s) of n frames from the first: k / fps plus clipped Gaussian jitter (0 exact)."""
    j = np.clip(rng.normal(0.0, jitter_s, n), -3 * jitter_s, 3 * jitter_s)
    j[0] = 0.0
    return np.arange(n) / fps + j


@dataclass(frozen=True)
class CanErrors:
    """speed_scale: relative speed error; yaw_bias_deg_s: yaw-rate offset; *_noise: noise std."""

    speed_scale: float
    speed_noise_kmh: float
    yaw_bias_deg_s: float
    yaw_noise_deg_s: float

    @staticmethod
    def random(rng: np.random.Generator) -> CanErrors:
        return CanErrors(
            speed_scale=float(rng.uniform(-0.01, 0.01)),
            speed_noise_kmh=0.05,
            yaw_bias_deg_s=float(rng.uniform(-0.2, 0.2)),
            yaw_noise_deg_s=0.1,
        )


class VehicleCan:
    """Encodes speed and yaw-rate frames through the DBC (the appliance decodes them likewise)."""

    def __init__(
        self,
        dbc_path: str | Path,
        errors: CanErrors,
        rng: np.random.Generator,
        channel: str = "can0",
    ) -> None:
        db = cantools.database.load_file(str(dbc_path))
        if not isinstance(db, cantools.database.can.Database):
            raise TypeError(f"{dbc_path} is not a CAN database")
        self.db = db
        self.speed_msg = self.db.get_message_by_name("VEHICLE_SPEED")
        self.yaw_msg = self.db.get_message_by_name("YAW_RATE")
        self.errors = errors
        self.rng = rng
        self.channel = channel

    def schedule(self, t_first: float, t_last: float) -> FloatArray:
        """Send times of the speed frames (yaw frames follow 10 ms later), with 0.2 ms jitter."""
        n = int(np.floor((t_last - t_first) / CAN_PERIOD_S)) + 1
        return t_first + CAN_PERIOD_S * np.arange(n) + self.rng.uniform(-0.0002, 0.0002, n)

    def messages(
        self,
        t: FloatArray,
        speed_m_s: FloatArray,
        yaw_rate_rad_s: FloatArray,
        yaw_t: FloatArray,
        yaw_rate_at_yaw_t: FloatArray,
    ) -> list[can.Message]:
        """Speed frames at ``t`` and yaw frames at ``yaw_t`` from the true signals, by time."""
        e = self.errors
        kmh = speed_m_s * 3.6 * (1.0 + e.speed_scale) + self.rng.normal(
            0, e.speed_noise_kmh, len(t)
        )
        kmh = np.clip(np.round(kmh, 2), 0.0, 655.35)
        dps = (
            np.degrees(yaw_rate_at_yaw_t)
            + e.yaw_bias_deg_s
            + self.rng.normal(0, e.yaw_noise_deg_s, len(yaw_t))
        )
        dps = np.clip(np.round(dps, 2), -327.68, 327.67)
        out = []
        for k, (ts, v) in enumerate(zip(t, kmh)):
            data = self.speed_msg.encode({"SPEED": float(v), "COUNTER": k % 16})
            out.append(self._msg(float(ts), self.speed_msg.frame_id, data))
        for k, (ts, w) in enumerate(zip(yaw_t, dps)):
            data = self.yaw_msg.encode({"YAW_RATE": float(w), "COUNTER": k % 16})
            out.append(self._msg(float(ts), self.yaw_msg.frame_id, data))
        out.sort(key=lambda m: m.timestamp)
        return out

    def _msg(self, t: float, frame_id: int, data: bytes) -> can.Message:
        # microsecond timestamps, as candump logs and SocketCAN give them
        return can.Message(
            timestamp=round(t, 6),
            arbitration_id=frame_id,
            is_extended_id=False,
            data=data,
            channel=self.channel,
            is_rx=True,
        )


def ptu_samples(rng: np.random.Generator, t_first: float, t_last: float) -> FloatArray:
    """Times (s) of the PTU position polls: 20 Hz with 1 ms jitter."""
    n = int(np.floor((t_last - t_first) / PTU_PERIOD_S)) + 1
    return t_first + PTU_PERIOD_S * np.arange(n) + rng.uniform(-0.001, 0.001, n)


def quantise_ptu(angle_rad: FloatArray) -> FloatArray:
    """What the PTU reports: the position rounded to whole steps."""
    return np.round(np.asarray(angle_rad) / PTU_STEP_RAD) * PTU_STEP_RAD
