"""Camera imperfections, chosen per seed: sensor noise, exposure flicker, motion blur."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

U8 = NDArray[np.uint8]


@dataclass(frozen=True)
class Effects:
    """noise_sigma: std of the sensor noise (DN); flicker: amplitude of the exposure gain
    variation (relative); blur_exposure: fraction of the frame interval the shutter is open
    (0 = no motion blur)."""

    noise_sigma: float = 0.0
    flicker: float = 0.0
    blur_exposure: float = 0.0

    @staticmethod
    def none() -> Effects:
        return Effects()

    @staticmethod
    def random(rng: np.random.Generator) -> Effects:
        """Always some noise; flicker on about half the seeds, motion blur on about a third."""
        return Effects(
            noise_sigma=float(rng.uniform(0.5, 2.0)),
            flicker=float(rng.uniform(0.01, 0.04)) if rng.random() < 0.5 else 0.0,
            blur_exposure=float(rng.uniform(0.2, 0.5)) if rng.random() < 0.35 else 0.0,
        )


class EffectsPipeline:
    """Applies :class:`Effects` frame by frame with its own random stream."""

    def __init__(self, effects: Effects, rng: np.random.Generator) -> None:
        self.fx = effects
        self.rng = rng
        q = ndtri((np.arange(256) + 0.5) / 256.0) * effects.noise_sigma  # uniform byte -> Gaussian
        q = np.clip(np.rint(q), -255, 255)
        self._pos = np.maximum(q, 0).astype(np.uint8)
        self._neg = np.maximum(-q, 0).astype(np.uint8)
        self._phase = float(rng.uniform(0, 2 * np.pi))

    def apply(self, img: U8, t: float, image_motion_px: tuple[float, float]) -> U8:
        """``image_motion_px``: image displacement (du, dv) over one frame at the image centre."""
        fx = self.fx
        if fx.blur_exposure > 0.0:
            du, dv = fx.blur_exposure * image_motion_px[0], fx.blur_exposure * image_motion_px[1]
            length = float(np.hypot(du, dv))
            if length > 0.5:
                n = int(np.ceil(length)) | 1
                k = np.zeros((n, n), np.float32)
                c = n // 2
                p0 = (c - du / 2.0, c - dv / 2.0)
                p1 = (c + du / 2.0, c + dv / 2.0)
                cv2.line(
                    k,
                    (int(round(p0[0] * 16)), int(round(p0[1] * 16))),
                    (int(round(p1[0] * 16)), int(round(p1[1] * 16))),
                    1.0,
                    1,
                    cv2.LINE_AA,
                    4,
                )
                k /= max(float(k.sum()), 1e-6)
                img = np.asarray(
                    cv2.filter2D(img, -1, k, borderType=cv2.BORDER_REPLICATE), np.uint8
                )
        if fx.flicker > 0.0:
            gain = 1.0 + fx.flicker * (
                0.7 * np.sin(2 * np.pi * 1.3 * t + self._phase)
                + 0.3 * float(self.rng.standard_normal())
            )
            img = np.asarray(cv2.convertScaleAbs(img, alpha=float(gain)), np.uint8)
        if fx.noise_sigma > 0.0:
            u = self.rng.integers(0, 256, img.shape, dtype=np.uint8)
            noisy = cv2.subtract(cv2.add(img, cv2.LUT(u, self._pos)), cv2.LUT(u, self._neg))
            img = np.asarray(noisy, np.uint8)
        return img
