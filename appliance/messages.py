"""Typed, frozen messages passed between the pipeline's stages.

Drivers -> ring buffers -> ``Frame`` + ``SensorSample`` -> vision (``EgoMotion``,
``ParticleSet``) -> decision (``TrackReport``, ``WarningEvent``) -> outputs.
Arrays inside messages are treated as read-only by every consumer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Frame:
    """One camera image. ``image`` is 8-bit gray (H, W); ``t`` on the recording clock, s."""

    index: int
    t: float
    image: NDArray[np.uint8]


@dataclass(frozen=True)
class SensorSample:
    """Vehicle and PTU state interpolated to a frame's capture time.

    speed_m_s: forward speed (m/s); yaw_rate_rad_s: CCW positive (rad/s);
    pan_rad / tilt_rad: PTU position (pan left +, tilt up +).
    ``can_valid`` is False when CAN data was missing or stale (values are then
    the last known ones or 0 and must not be trusted); ``ptu_valid`` likewise.
    """

    t: float
    speed_m_s: float
    yaw_rate_rad_s: float
    pan_rad: float = 0.0
    tilt_rad: float = 0.0
    can_valid: bool = True
    ptu_valid: bool = True


@dataclass(frozen=True)
class EgoMotion:
    """Camera motion from the previous frame to this one, camera frame.

    ``X_cur = R(rotation) @ X_prev + t`` with ``t`` parallel to ``translation_dir``
    (unit vector; zeros at standstill). Euler angles as in ``vision.geometry``.
    ``epipole_px`` is ``K t`` in ideal pixels, None when it lies at infinity.
    The ``prior_*`` fields are the mean of eq. 9, computed from CAN and PTU.
    ``confident`` is False when refinement kept the prior (too few
    correspondences) or the prior itself was widened (CAN missing).
    """

    rotation: NDArray[np.float64]
    translation_dir: NDArray[np.float64]
    epipole_px: tuple[float, float] | None
    prior_rotation: NDArray[np.float64]
    prior_translation_dir: NDArray[np.float64]
    prior_epipole_px: tuple[float, float] | None
    inliers: int
    confident: bool
    standstill: bool = False


@dataclass(frozen=True)
class ParticleSet:
    """Where optical flow was measured on this frame, and what it says.

    positions: (N, 2) float, particle positions in the *current* frame (px), i.e.
    the end points ``x_t`` of the measured correspondences.
    flow: (N, 2) float, measured flow ``x_t - x_{t-1}`` (px/frame).
    weights: (N,) float in [0, 1], likelihood of independent motion at each
    particle (eq. 6, combined with the flow-length cue), before resampling.
    valid: (N,) bool, False where the flow could not be measured.
    window_px: the Lucas-Kanade window the flows were measured with (px, square): a particle
    beside an object still follows it up to half of it away (the halo).
    flow_std_px: the flows' accuracy, sigma_p of eq. 5 (px).
    """

    positions: NDArray[np.float64]
    flow: NDArray[np.float64]
    weights: NDArray[np.float64]
    valid: NDArray[np.bool_]
    window_px: int
    flow_std_px: float


@dataclass(frozen=True)
class ProbabilityMap:
    """Spatio-temporally filtered probability of independent motion, p(x) (section 4).

    ``p`` has shape (ceil(H / scale), ceil(W / scale)), values in [0, 1]; pixel
    (u, v) of the image maps to ``p[int(v) // scale, int(u) // scale]``. The
    vision core samples its static-scene correspondences with probability
    1 - p(x) (fig. 6, step 1).
    """

    p: NDArray[np.float32]
    scale: int

    def at(self, uv: NDArray[np.floating]) -> NDArray[np.float32]:
        """p(x) at image pixels ``uv`` (N, 2); pixels outside the image get 0."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        h, w = self.p.shape
        col = np.floor(uv[:, 0] / self.scale).astype(np.int64)
        row = np.floor(uv[:, 1] / self.scale).astype(np.int64)
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.zeros(len(uv), dtype=np.float32)
        out[inside] = self.p[row[inside], col[inside]]
        return out


@dataclass(frozen=True)
class TrackReport:
    """One confirmed track as written to ``tracks.jsonl`` (spec). ``reason``: why it warns or
    what keeps it from warning ("warning", "caution", "not moving over ground", "ttc 3.4 s
    above 3.0 s", ...; see ``decision/warnings.py``)."""

    id: int
    bbox: tuple[float, float, float, float]
    probability: float
    flow: tuple[float, float]
    ttc_s: float | None
    distance_m: float | None
    bearing_rad: float | None = None
    reason: str | None = None


@dataclass(frozen=True)
class WarningEvent:
    """A warning state change as written to ``warnings.jsonl`` (spec)."""

    t: float
    frame: int
    level: int
    track: int | None
    bbox: tuple[float, float, float, float] | None
    ttc_s: float | None
    distance_m: float | None
    bearing_rad: float | None


@dataclass(frozen=True)
class StepOutput:
    """Everything one pipeline step produced for one frame."""

    frame: int
    t: float
    ego: EgoMotion
    particles: ParticleSet
    tracks: tuple[TrackReport, ...]
    warnings: tuple[WarningEvent, ...]
    warning_level: int
    stage_ms: dict[str, float] = field(default_factory=dict)
