"""Vehicle CAN and PTU samples interpolated to a frame's capture time.

The processing thread owns one :class:`SensorSync`; it feeds it the samples that
the drivers (live) or the recording (replay) delivered, then asks for a
:class:`~appliance.messages.SensorSample` at each frame's capture time. Between
two samples the value is interpolated linearly; after the newest sample it is
held (CAN) or continued along the last two samples' slope (the PTU's pan and tilt).
A signal whose nearest sample is older than ``stale_s`` is invalid (``can_valid`` /
``ptu_valid`` False); with no PTU at all the PTU is at zero and valid, as the spec
says for a recording without ``ptu.csv``.
"""

from __future__ import annotations

import math

import bisect
from dataclasses import dataclass

from appliance.messages import SensorSample


@dataclass(frozen=True)
class SignalReading:
    """An interpolated value and whether it is fresh."""

    value: float
    fresh: bool


class SignalHistory:
    """Time-ordered samples of one scalar signal, trimmed to the last ``keep_s`` seconds."""

    def __init__(self, keep_s: float = 5.0) -> None:
        self.keep_s = keep_s
        self._t: list[float] = []
        self._v: list[float] = []

    def add(self, t: float, value: float) -> None:
        if self._t and t < self._t[-1]:
            # late sample (another source, reordering): keep the history sorted
            i = bisect.bisect_right(self._t, t)
            self._t.insert(i, t)
            self._v.insert(i, value)
        else:
            self._t.append(t)
            self._v.append(value)
        horizon = self._t[-1] - self.keep_s
        if self._t[0] < horizon:
            cut = bisect.bisect_left(self._t, horizon)
            del self._t[:cut]
            del self._v[:cut]

    def __len__(self) -> int:
        return len(self._t)

    def at(self, t: float, stale_s: float, extrapolate: bool = False) -> SignalReading | None:
        """Value at ``t``: interpolated between neighbours, held after the newest (with
        ``extrapolate``: continued along the last two samples' slope for at most ``stale_s``);
        None if empty."""
        if not self._t:
            return None
        i = bisect.bisect_left(self._t, t)
        if i < len(self._t) and self._t[i] == t:
            return SignalReading(self._v[i], True)
        if i == 0:
            return SignalReading(self._v[0], self._t[0] - t <= stale_s)
        if i == len(self._t):
            fresh = t - self._t[-1] <= stale_s
            if extrapolate and len(self._t) >= 2 and self._t[-1] > self._t[-2]:
                slope = (self._v[-1] - self._v[-2]) / (self._t[-1] - self._t[-2])
                return SignalReading(self._v[-1] + slope * min(t - self._t[-1], stale_s), fresh)
            return SignalReading(self._v[-1], fresh)
        t0, t1 = self._t[i - 1], self._t[i]
        w = (t - t0) / (t1 - t0)
        value = self._v[i - 1] * (1.0 - w) + self._v[i] * w
        return SignalReading(value, min(t - t0, t1 - t) <= stale_s)


class SensorSync:
    """Speed, yaw rate, pan and tilt histories; :meth:`sample` gives them at a frame time.

    :param can_stale_s: a CAN signal farther than this from the frame time is stale.
    :param ptu_stale_s: likewise for the PTU position.
    :param ptu_present: False when there is no PTU (fixed at zero, always valid).
    """

    def __init__(self, can_stale_s: float, ptu_stale_s: float, ptu_present: bool = True) -> None:
        self.can_stale_s = can_stale_s
        self.ptu_stale_s = ptu_stale_s
        self.ptu_present = ptu_present
        self.speed = SignalHistory()
        self.yaw_rate = SignalHistory()
        self.pan = SignalHistory()
        self.tilt = SignalHistory()
        # unknown until the first CAN sample (NaN, can_valid False): not a car standing still
        self._last_speed = math.nan
        self._last_yaw = math.nan
        self._last_pan = 0.0
        self._last_tilt = 0.0

    def add_speed(self, t: float, speed_m_s: float) -> None:
        self.speed.add(t, speed_m_s)

    def add_yaw_rate(self, t: float, yaw_rate_rad_s: float) -> None:
        self.yaw_rate.add(t, yaw_rate_rad_s)

    def add_ptu(self, t: float, pan_rad: float, tilt_rad: float) -> None:
        self.pan.add(t, pan_rad)
        self.tilt.add(t, tilt_rad)

    def sample(self, t: float) -> SensorSample:
        """Sensors at frame time ``t``; stale or missing signals keep their last value, flagged."""
        sp = self.speed.at(t, self.can_stale_s)
        yr = self.yaw_rate.at(t, self.can_stale_s)
        can_valid = sp is not None and yr is not None and sp.fresh and yr.fresh
        if sp is not None:
            self._last_speed = sp.value
        if yr is not None:
            self._last_yaw = yr.value
        if not self.ptu_present:
            return SensorSample(t, self._last_speed, self._last_yaw, 0.0, 0.0, can_valid, True)
        # the PTU answers position queries at ~20 Hz, so a frame's time is often past its newest
        # answer: during a pan (20 deg/s) holding that answer puts the prior up to 1 deg behind
        pa = self.pan.at(t, self.ptu_stale_s, extrapolate=True)
        ti = self.tilt.at(t, self.ptu_stale_s, extrapolate=True)
        ptu_valid = pa is not None and ti is not None and pa.fresh and ti.fresh
        if pa is not None and ti is not None:
            self._last_pan, self._last_tilt = pa.value, ti.value
        return SensorSample(
            t,
            self._last_speed,
            self._last_yaw,
            self._last_pan,
            self._last_tilt,
            can_valid,
            ptu_valid,
        )
