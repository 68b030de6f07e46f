"""The most a track has shown of itself: its highest probability of independent motion and
its tallest box at its depth.

Both outlast the moments that thin a track out: an occluder thins its region out before it is
lost (a hidden track is assessed with the probability it had while seen), and a pedestrian's
box shrinks to its feet when its upper body's flow is lost (it stays a road user, not a strip
of road: ``warning.min_height_m``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from appliance.decision.cues.base import CueInput
from appliance.decision.object_extent import extended
from appliance.decision.tracking import ImageTrack
from appliance.vision.geometry import PinholeCamera


@dataclass(frozen=True)
class PeakState:
    """The highest (smoothed) eq. 20 probability of the track so far, and the tallest (m) its
    reported box has been at its depth while seen, this frame included (``height_m``: this
    frame's, None when not measured)."""

    probability: float = 0.0
    height_peak_m: float = 0.0
    height_m: float | None = None


def clip_box(box: tuple[float, float, float, float], camera: PinholeCamera
             ) -> tuple[float, float, float, float]:
    """The track box inside the image, rounded to 0.1 px (a coasting track may drift out)."""
    u0, v0, u1, v1 = box
    w, h = float(camera.width), float(camera.height)
    return (round(min(max(u0, 0.0), w), 1), round(min(max(v0, 0.0), h), 1),
            round(min(max(u1, 0.0), w), 1), round(min(max(v1, 0.0), h), 1))


def shown(track: ImageTrack, cues: Mapping[str, Any]) -> ImageTrack:
    """The track as reported: its box reaching up to its outline's top and down to its foot
    (the states of the ``outline`` and ``foot`` cues in ``cues``, where they have one)."""
    outline, foot = cues.get("outline"), cues.get("foot")
    if outline is None and foot is None:
        return track
    top = outline.top if outline is not None else track.bbox[1]
    return extended(track, top, foot.bottom if foot is not None and foot.rows > 0 else None)


class Peaks:
    name: ClassVar[str] = "peaks"
    estimates_ground: ClassVar[bool] = False

    def update(self, prev: PeakState | None, x: CueInput, cfg: None) -> PeakState:
        prev = prev if prev is not None else PeakState()
        tr, f, g = x.track, x.frame, x.ground
        found = x.found.get(self.name) if x.found is not None else None
        peak = max(prev.height_peak_m, found.height_peak_m if found is not None else 0.0)
        height: float | None = None
        if tr.confirmed and tr.cluster is not None and g is not None:
            depth = float(g.position[0] - f.mount.x_m)
            if depth > 0.0:
                _, v0, _, v1 = clip_box(shown(tr, x.now).bbox, f.camera)
                height = (v1 - v0) * depth / f.camera.fy
                peak = max(peak, height)
        return PeakState(probability=max(prev.probability, float(tr.probability)),
                         height_peak_m=peak, height_m=height)
