"""The track's bearing history, and the bearing rate fitted to it.

The azimuth of the track (vehicle frame, rad) every frame, the last ``HISTORY`` frames. Its
rate is the classic monocular collision-course test (a constant bearing) and gives a new 3-D
state its velocity across the line of sight. The history restarts when the point the bearing
is taken at changes (the box reached or left an image border, ``frame.bearing_pixel``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from appliance.decision.cues.base import CueInput

HISTORY = 10  # frames of bearing kept


@dataclass(frozen=True)
class BearingState:
    """(t s, bearing rad) of the last frames, oldest first, and where they were taken."""

    history: tuple[tuple[float, float], ...]
    ref: str

    @property
    def last(self) -> float | None:
        return self.history[-1][1] if self.history else None

    @property
    def rate(self) -> float | None:
        """Least-squares slope (rad/s) of the history; None with fewer than 3 frames."""
        return bearing_rate(self.history)


def bearing_fit(hist: tuple[tuple[float, float], ...]) -> tuple[float, float] | None:
    """Least-squares slope (rad/s) of the history and its standard error from the fit's
    residuals (rad/s); None with fewer than 3 frames or no time between them. A young track's
    first boxes (a sliver of the object, growing) turn its bearing more than the object does:
    few points and a large residual."""
    if len(hist) < 3:
        return None
    ts = np.array([h[0] for h in hist])
    bs = np.unwrap(np.array([h[1] for h in hist]))
    if ts[-1] - ts[0] <= 0.0:
        return None
    slope, intercept = np.polyfit(ts - ts[-1], bs, 1)
    residual = bs - (slope * (ts - ts[-1]) + intercept)
    spread = float(np.sum((ts - ts.mean()) ** 2))
    return float(slope), float(np.sqrt(np.sum(residual ** 2) / (len(hist) - 2) / spread))


def bearing_rate(hist: tuple[tuple[float, float], ...]) -> float | None:
    fit = bearing_fit(hist)
    return None if fit is None else fit[0]


class Bearing:
    name: ClassVar[str] = "bearing"
    estimates_ground: ClassVar[bool] = False

    def update(self, prev: BearingState | None, x: CueInput, cfg: None) -> BearingState:
        ref = x.meas.bearing_ref
        hist = prev.history if prev is not None and prev.ref == ref else ()
        hist = (hist + ((x.frame.t, x.meas.bearing),))[-HISTORY:]
        found = x.found.get(self.name) if x.found is not None else None
        if found is not None and found.ref == ref:
            hist = (found.history + hist)[-HISTORY:]
        return BearingState(history=hist, ref=ref)
