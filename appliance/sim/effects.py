"""What the camera does to the rendered scene: blur, exposure, vignetting, colour and noise.

The renderer gives each pixel's luminance. Per frame, in the order light meets the sensor:
motion blur along the image motion during the shutter time, optical blur (Gaussian),
exposure (a mean gain, a slow drift, an optional fast flicker) times the vignetting
fall-off towards the corners, then the colour filter (colour cameras) and the sensor noise.

Colour frames are BGR. Each object has its own colour (a chroma per object id, over a
white-balance cast of the whole frame), at half the resolution as a Bayer sensor's
demosaicked chroma, with the luma weights of OpenCV's ``COLOR_BGR2GRAY`` (BT.601) kept:
converted to gray, as the appliance reads a colour recording, a frame gives back the
rendered luminance except where a channel saturates, plus the noise, which is drawn per
channel (gray noise about 0.67 of its std).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]

LUMA_BGR = np.array([0.114, 0.587, 0.299])  # OpenCV's BGR -> gray weights (BT.601)


@dataclass(frozen=True)
class Effects:
    """colour: BGR frames (else gray); saturation: largest chroma of an object's colour;
    white_balance: chroma of the cast over the whole frame; exposure: mean gain; drift:
    amplitude of a slow sinusoidal gain drift (relative) with period drift_period_s; flicker:
    amplitude of a fast exposure gain variation (relative); vignetting: relative fall-off in
    the image corners; blur_sigma: optical blur (px); blur_exposure: fraction of the frame
    interval the shutter is open (0 = no motion blur); noise_sigma: std of the sensor noise
    (DN, per channel). The default is a perfect gray camera."""

    colour: bool = False
    saturation: float = 0.0
    white_balance: float = 0.0
    exposure: float = 1.0
    drift: float = 0.0
    drift_period_s: float = 10.0
    flicker: float = 0.0
    vignetting: float = 0.0
    blur_sigma: float = 0.0
    blur_exposure: float = 0.0
    noise_sigma: float = 0.0

    @staticmethod
    def none() -> Effects:
        return Effects()


def _chroma_basis() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two orthonormal BGR directions that leave the luma unchanged."""
    e1 = np.cross(LUMA_BGR, np.ones(3))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(LUMA_BGR, e1)
    e2 /= np.linalg.norm(e2)
    return e1, e2


def palette(
    rng: np.random.Generator, n: int, saturation: float, white_balance: float
) -> F32:
    """BGR gains (n, 3) of object ids 0..n-1 whose luma (``LUMA_BGR``) is exactly 1: the frame's
    cast for every id, and for ids >= 1 (objects) a colour of random hue and a chroma up to
    ``saturation`` on top."""
    e1, e2 = _chroma_basis()
    a = rng.uniform(0.0, 2.0 * np.pi)
    cast = white_balance * (np.cos(a) * e1 + np.sin(a) * e2)
    hue = rng.uniform(0.0, 2.0 * np.pi, n)
    chroma = rng.uniform(0.0, saturation, n)
    chroma[0] = 0.0  # road, sidewalk, sky: the cast only
    d = chroma[:, None] * (np.cos(hue)[:, None] * e1 + np.sin(hue)[:, None] * e2)
    gains: F32 = (1.0 + cast + d).astype(np.float32)
    return gains


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
        self._drift_phase = float(rng.uniform(0, 2 * np.pi))
        self._palette: F32 | None = None
        if effects.colour:
            self._palette = palette(rng, 2**16, effects.saturation, effects.white_balance)
        self._vignette: dict[tuple[int, ...], F32] = {}

    def gain(self, t: float) -> float:
        """Exposure gain of the frame at ``t``: mean, slow drift and flicker (draws one number
        per frame when there is flicker)."""
        fx = self.fx
        g = fx.exposure
        if fx.drift > 0.0:
            g *= 1.0 + fx.drift * np.sin(2 * np.pi * t / fx.drift_period_s + self._drift_phase)
        if fx.flicker > 0.0:
            g *= 1.0 + fx.flicker * (
                0.7 * np.sin(2 * np.pi * 1.3 * t + self._phase)
                + 0.3 * float(self.rng.standard_normal())
            )
        return float(g)

    def vignette(self, shape: tuple[int, ...]) -> F32:
        """Relative light falling on each pixel (1 at the centre, 1 - vignetting at the
        corners), of an image ``shape`` (gray or colour)."""
        if shape not in self._vignette:
            h, w = shape[:2]
            v, u = np.mgrid[0:h, 0:w].astype(np.float32)
            r2 = (((u - (w - 1) / 2) / (w / 2)) ** 2 + ((v - (h - 1) / 2) / (h / 2)) ** 2) / 2
            m = (1.0 - self.fx.vignetting * r2).astype(np.float32)
            self._vignette[shape] = m if len(shape) == 2 else cv2.merge([m] * shape[2])
        return self._vignette[shape]

    def apply(
        self,
        img: U8,
        t: float,
        image_motion_px: tuple[float, float],
        ids: NDArray[np.uint16] | None = None,
    ) -> U8:
        """The camera's frame of a rendered luminance image ``img`` (H, W) at ``t``:
        ``image_motion_px`` is the image displacement (du, dv) over one frame at the image
        centre; ``ids`` the object id of each pixel (needed for colour). Returns (H, W) gray
        or (H, W, 3) BGR."""
        fx = self.fx
        if fx.blur_exposure > 0.0:
            img = self._motion_blur(img, image_motion_px)
        if fx.blur_sigma > 0.0:
            img = np.asarray(cv2.GaussianBlur(img, (0, 0), fx.blur_sigma), np.uint8)
        gain = self.gain(t)
        if self._palette is not None:
            if ids is None:
                raise ValueError("a colour camera needs the object ids of the pixels")
            h, w = img.shape
            chroma = cv2.resize(
                self._palette[ids[::2, ::2]], (w, h), interpolation=cv2.INTER_LINEAR
            )
            if fx.vignetting > 0.0:
                chroma = cv2.multiply(chroma, self.vignette(chroma.shape))
            img = np.asarray(
                cv2.multiply(cv2.merge([img] * 3), chroma, scale=gain, dtype=cv2.CV_8U),
                np.uint8,
            )
        elif fx.vignetting > 0.0:
            img = np.asarray(
                cv2.multiply(img, self.vignette(img.shape), scale=gain, dtype=cv2.CV_8U),
                np.uint8,
            )
        elif gain != 1.0:
            img = np.asarray(cv2.convertScaleAbs(img, alpha=gain), np.uint8)
        if fx.noise_sigma > 0.0:
            u = self.rng.integers(0, 256, img.shape, dtype=np.uint8)
            noisy = cv2.subtract(cv2.add(img, cv2.LUT(u, self._pos)), cv2.LUT(u, self._neg))
            img = np.asarray(noisy, np.uint8)
        return img

    def _motion_blur(self, img: U8, image_motion_px: tuple[float, float]) -> U8:
        b = self.fx.blur_exposure
        du, dv = b * image_motion_px[0], b * image_motion_px[1]
        length = float(np.hypot(du, dv))
        if length <= 0.5:
            return img
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
        return np.asarray(cv2.filter2D(img, -1, k, borderType=cv2.BORDER_REPLICATE), np.uint8)
