"""Annotated video for ``replay --video``: particles, clusters, tracks, epipole, warning banner.

Drawing only; it reads the step's outputs and never feeds anything back.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.errors import UsageError
from appliance.messages import Frame, StepOutput

LEVEL_COLOURS = {0: (80, 200, 80), 1: (0, 200, 255), 2: (0, 0, 255)}
LEVEL_TEXT = {1: "CAUTION", 2: "WARNING"}


def annotate(frame: Frame, out: StepOutput, clusters: tuple[Any, ...] = ()) -> NDArray[np.uint8]:
    """A BGR image of ``frame`` with what the pipeline found on it."""
    img: NDArray[np.uint8] = np.asarray(
        cv2.cvtColor(frame.image, cv2.COLOR_GRAY2BGR), dtype=np.uint8
    )
    p = out.particles
    if len(p.positions):
        pts = np.round(p.positions[p.valid]).astype(np.int32)
        wts = p.weights[p.valid]
        for (u, v), w in zip(pts, wts):
            c = (0, int(255 * (1 - w)), int(255 * w))
            cv2.circle(img, (int(u), int(v)), 1, c, -1, lineType=cv2.LINE_AA)
    for c in clusters:
        box = getattr(c, "bbox", None)
        if box is not None:
            u0, v0, u1, v1 = (int(round(x)) for x in box)
            cv2.rectangle(img, (u0, v0), (u1, v1), (255, 160, 0), 1)
    if out.ego.epipole_px is not None:
        eu, ev = out.ego.epipole_px
        if abs(eu) < 1e5 and abs(ev) < 1e5:
            cv2.drawMarker(
                img, (int(round(eu)), int(round(ev))), (255, 0, 255), cv2.MARKER_CROSS, 14, 1
            )
    for tr in out.tracks:
        u0, v0, u1, v1 = (int(round(x)) for x in tr.bbox)
        cv2.rectangle(img, (u0, v0), (u1, v1), (0, 255, 255), 2)
        ttc = "-" if tr.ttc_s is None else f"{tr.ttc_s:.1f}s"
        dist = "" if tr.distance_m is None else f" {tr.distance_m:.0f}m"
        cv2.putText(
            img,
            f"#{tr.id} {ttc}{dist}",
            (u0, max(12, v0 - 4)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.45,
            (0, 255, 255),
            1,
            cv2.LINE_AA,
        )
    level = out.warning_level
    if level > 0:
        cv2.rectangle(img, (0, 0), (img.shape[1], 28), LEVEL_COLOURS[level], -1)
        cv2.putText(
            img,
            LEVEL_TEXT[level],
            (10, 21),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.7,
            (255, 255, 255),
            2,
            cv2.LINE_AA,
        )
    cv2.putText(
        img,
        f"{frame.index} t={frame.t:.2f}",
        (8, img.shape[0] - 8),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.4,
        (255, 255, 255),
        1,
        cv2.LINE_AA,
    )
    return img


class AnnotatedVideo:
    """Writes annotated frames to ``path`` (MJPG in .avi, else mp4v; FFV1 for .mkv)."""

    def __init__(self, path: str | Path, size: tuple[int, int], fps: float) -> None:
        self.path = Path(path)
        fourcc = {".avi": "MJPG", ".mkv": "FFV1"}.get(self.path.suffix.lower(), "mp4v")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._vw = cv2.VideoWriter(str(self.path), cv2.VideoWriter.fourcc(*fourcc), fps, size)
        if not self._vw.isOpened():
            raise UsageError(f"{self.path}: cannot write video ({fourcc})")
        self.frames = 0

    def write(self, image: NDArray[np.uint8]) -> None:
        self._vw.write(image)
        self.frames += 1

    def close(self) -> None:
        self._vw.release()
