"""Procedural textures for the simulated world, with anti-aliasing rip-maps.

Every texture is generated from a seeded ``numpy.random.Generator``: the same
seed gives the same bytes. Textures carry plenty of corners at every scale
(1/f noise, slab joints, windows, patches) because the vision core tracks
Lucas-Kanade points on them.

A :class:`Texture` holds a *rip-map*: the image pre-filtered and down-sampled by
``2**lu`` along its u axis and ``2**lv`` along its v axis, independently. The
renderer picks the level from the projected size of a texel along each texture
axis, so a road seen at a grazing angle is blurred along the road only and
distant surfaces do not alias (aliasing makes false optical flow).

Wrapping textures (``wrap=True``) are exactly periodic, including all their
levels, so one texture can cover an unbounded plane through ``BORDER_WRAP``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]


@dataclass(frozen=True)
class Texture:
    """A gray texture and its rip-map.

    ``levels[lu][lv]`` is the image down-sampled ``2**lu`` times along u (columns)
    and ``2**lv`` times along v (rows). ``texel_m`` is the size (m) of one level-0
    texel along (u, v) for wrapping textures; stretched textures get their texel
    size from the face they cover.
    """

    name: str
    levels: tuple[tuple[U8, ...], ...]
    wrap: bool
    texel_m: tuple[float, float] = (0.01, 0.01)
    _sources: dict[tuple[int, int], tuple[U8, int, int]] = field(
        default_factory=dict, compare=False, repr=False
    )

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width) of level 0, texels."""
        h, w = self.levels[0][0].shape
        return int(h), int(w)

    @property
    def period_m(self) -> tuple[float, float]:
        """Repeat period (m) along (u, v) of a wrapping texture."""
        h, w = self.shape
        return w * self.texel_m[0], h * self.texel_m[1]

    def level(self, lu: int, lv: int) -> U8:
        lu = min(max(lu, 0), len(self.levels) - 1)
        lv = min(max(lv, 0), len(self.levels[lu]) - 1)
        return self.levels[lu][lv]

    @property
    def max_levels(self) -> tuple[int, int]:
        return len(self.levels) - 1, len(self.levels[0]) - 1

    def source(self, lu: int, lv: int) -> tuple[U8, int, int]:
        """Level (lu, lv) prepared for ``warpPerspective`` with ``BORDER_TRANSPARENT``, which is
        about three times faster than the wrap or replicate borders: a wrapping level tiled
        (ku, kv) times (at least 3 periods and ``SOURCE_MIN`` texels, at most ``SOURCE_MAX``), a
        stretched one padded by ``PAD`` replicated texels. Returns (image, ku, kv); built on
        first use.
        """
        key = (lu, lv)
        if key not in self._sources:
            lev = self.levels[lu][lv]
            h, w = lev.shape
            if self.wrap:  # >= 3 periods and >= SOURCE_MIN texels, at most SOURCE_MAX
                ku = max(1, min(SOURCE_MAX // w, max(3, -(-SOURCE_MIN // w))))
                kv = max(1, min(SOURCE_MAX // h, max(3, -(-SOURCE_MIN // h))))
                img = np.ascontiguousarray(np.tile(lev, (kv, ku)))
            else:
                ku = kv = 1
                img = np.asarray(
                    cv2.copyMakeBorder(lev, PAD, PAD, PAD, PAD, cv2.BORDER_REPLICATE), np.uint8
                )
            self._sources[key] = (img, ku, kv)
        return self._sources[key]


PAD = 3  # texels of replicated border around stretched textures (see Texture.source)
SOURCE_MIN = 512  # texels: smallest side of a tiled wrapping level
SOURCE_MAX = 2048  # texels: largest side of a tiled wrapping level


def make_texture(
    name: str, image: U8, wrap: bool, texel_m: tuple[float, float] = (0.01, 0.01), min_size: int = 2
) -> Texture:
    """Build the rip-map of ``image`` by box-filtered down-sampling (``INTER_AREA``).

    For a wrapping texture every level stays periodic as long as the size is
    divisible by ``2**level``; levels stop where that no longer holds.
    """
    img = np.ascontiguousarray(image, dtype=np.uint8)
    h, w = img.shape

    def n_levels(size: int) -> int:
        n = 0
        while size % (2 ** (n + 1)) == 0 and size // (2 ** (n + 1)) >= min_size:
            n += 1
        if not wrap:  # stretched textures may shrink to any size
            n = max(0, int(np.floor(np.log2(max(size, 1) / min_size))))
        return n

    nu, nv = n_levels(w), n_levels(h)
    levels = []
    for lu in range(nu + 1):
        row = []
        for lv in range(nv + 1):
            size = (max(1, w >> lu), max(1, h >> lv))
            lev = img if (lu, lv) == (0, 0) else cv2.resize(img, size, interpolation=cv2.INTER_AREA)
            row.append(np.ascontiguousarray(lev, dtype=np.uint8))
        levels.append(tuple(row))
    return Texture(name, tuple(levels), wrap, texel_m)


def with_contrast(texture: Texture, contrast: float) -> Texture:
    """The texture with its deviations from its mean scaled by ``contrast`` (clipped to 0-255).

    Applied to every rip-map level: the levels are box-filtered copies of level 0, and the
    change is affine, so each stays the filtered copy of the new level 0.
    """
    if contrast == 1.0:
        return texture
    mean = float(texture.levels[0][0].mean())
    lut = np.clip(np.rint(mean + contrast * (np.arange(256) - mean)), 0, 255).astype(np.uint8)
    levels = tuple(tuple(np.asarray(cv2.LUT(lev, lut), np.uint8) for lev in row)
                   for row in texture.levels)
    return Texture(texture.name, levels, texture.wrap, texture.texel_m)


# ---------------------------------------------------------------- noise primitives


def pink_noise(
    rng: np.random.Generator,
    shape: tuple[int, int],
    beta: float = 1.0,
    low_cut: float = 1.0,
    high_cut: float | None = None,
) -> F32:
    """Periodic 1/f**beta noise (zero mean, unit std), shape (H, W), float32.

    ``low_cut``/``high_cut`` limit the spatial frequencies (cycles per image).
    Periodic by construction (FFT), so it tiles seamlessly.
    """
    h, w = shape
    fy = np.fft.fftfreq(h)[:, None] * h
    fx = np.fft.rfftfreq(w)[None, :] * w
    f = np.sqrt(fx**2 + fy**2)
    amp = np.zeros_like(f)
    band = f >= low_cut
    if high_cut is not None:
        band &= f <= high_cut
    amp[band] = 1.0 / f[band] ** beta
    spec = amp * (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape))
    out = np.fft.irfft2(spec, s=(h, w))
    out -= out.mean()
    std = out.std()
    return (out / (std if std > 0 else 1.0)).astype(np.float32)


def wrapped_draw(draw: Callable[[int, int], None], w: int, h: int) -> None:
    """Call ``draw(dx, dy)`` for the 3x3 periodic copies so shapes wrap around."""
    for dy in (-h, 0, h):
        for dx in (-w, 0, w):
            draw(dx, dy)


def blur_wrap(img: NDArray[np.floating], sigma: float) -> F32:
    """Gaussian blur of a periodic image (``GaussianBlur`` has no wrap border: pad, blur, crop)."""
    r = int(np.ceil(3 * sigma)) + 1
    h, w = img.shape
    pad = cv2.copyMakeBorder(np.asarray(img, np.float32), r, r, r, r, cv2.BORDER_WRAP)
    out = cv2.GaussianBlur(pad, (2 * r + 1, 2 * r + 1), sigma, borderType=cv2.BORDER_REFLECT)
    return np.ascontiguousarray(out[r : r + h, r : r + w])


def to_u8(img: NDArray[Any]) -> U8:
    out: U8 = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return out


def grain(rng: np.random.Generator, shape: tuple[int, int], amp: float, blur: float = 0.6) -> F32:
    g = rng.standard_normal(shape).astype(np.float32)
    if blur > 0:
        g = blur_wrap(g, blur)
        g /= max(float(g.std()), 1e-6)
    return g * amp


# ---------------------------------------------------------------- ground


def asphalt(rng: np.random.Generator, size: int = 1024, texel_m: float = 0.01) -> Texture:
    """Asphalt: multi-scale 1/f noise, stains, repair patches and grain; wraps."""
    shape = (size, size)
    img = 100.0 + 13.0 * pink_noise(rng, shape, beta=0.9, low_cut=2.0)
    stains = pink_noise(rng, shape, beta=1.6, low_cut=3.0)
    img -= 18.0 * (stains > 1.1)  # sharp-edged oil/wet stains give corners at a distance
    img += 12.0 * (stains < -1.4)
    patch = np.zeros(shape, np.float32)
    for _ in range(int(rng.integers(5, 9))):
        cx, cy = rng.uniform(0, size, 2)
        pw, ph = rng.uniform(0.4, 1.6, 2) / texel_m
        ang = float(rng.uniform(-10, 10))
        val = float(rng.choice([-16.0, 14.0]))
        box = cv2.boxPoints(((float(cx), float(cy)), (float(pw), float(ph)), ang))

        def draw(dx: int, dy: int, box: np.ndarray = box, val: float = val) -> None:
            cv2.fillConvexPoly(patch, np.rint(box + (dx, dy)).astype(np.int32), val)

        wrapped_draw(draw, size, size)
    img += patch
    cracks = np.zeros(shape, np.float32)
    for _ in range(int(rng.integers(6, 12))):
        p = rng.uniform(0, size, 2)
        heading = rng.uniform(0, 2 * np.pi)
        pts = [p.copy()]
        for _ in range(int(rng.integers(8, 25))):
            heading += rng.normal(0, 0.5)
            p = p + 12.0 * np.array([np.cos(heading), np.sin(heading)])
            pts.append(p.copy())
        poly = np.rint(np.array(pts)).astype(np.int32)

        def draw_c(dx: int, dy: int, poly: np.ndarray = poly) -> None:
            cv2.polylines(cracks, [poly + (dx, dy)], False, -30.0, 2)

        wrapped_draw(draw_c, size, size)
    img += cracks
    img += grain(rng, shape, 7.0, 0.7)
    img += 10.0 * (rng.random(shape) < 0.004)  # bright chippings
    img = blur_wrap(img.astype(np.float32), 0.6)
    return make_texture("asphalt", to_u8(img), True, (texel_m, texel_m))


def paving(
    rng: np.random.Generator, size: int = 512, slab: int = 32, texel_m: float = 0.015625
) -> Texture:
    """Sidewalk paving slabs with dark joints and per-slab brightness; wraps."""
    shape = (size, size)
    img = np.zeros(shape, np.float32)
    n = size // slab
    base = float(rng.uniform(135, 165))
    for j in range(n):
        shift = (slab // 2) * (j % 2)
        for i in range(n + 1):
            x0 = i * slab + shift
            val = base + float(rng.normal(0, 12))

            def draw(dx: int, dy: int, x0: int = x0, val: float = val, j: int = j) -> None:
                cv2.rectangle(
                    img,
                    (x0 + dx, j * slab + dy),
                    (x0 + slab - 1 + dx, (j + 1) * slab - 1 + dy),
                    val,
                    -1,
                )

            wrapped_draw(draw, size, size)
    img += 6.0 * pink_noise(rng, shape, beta=1.0, low_cut=2.0)
    img += grain(rng, shape, 6.0, 0.8)
    for j in range(n):  # joints
        img[j * slab : j * slab + 2, :] = base - 55
        shift = (slab // 2) * (j % 2)
        for i in range(n + 1):
            x = (i * slab + shift) % size
            img[j * slab : (j + 1) * slab, x : x + 2] = base - 55
    img = blur_wrap(img, 0.7)
    return make_texture("paving", to_u8(img), True, (texel_m, texel_m))


def kerb(rng: np.random.Generator, texel_m: float = 0.015625) -> Texture:
    """Kerb stones 1 m long (64 texels) with joints, 8 texels tall; wraps."""
    w, h = 256, 8
    img = np.zeros((h, w), np.float32)
    for i in range(4):
        img[:, i * 64 : (i + 1) * 64] = float(rng.uniform(165, 200))
        img[:, i * 64 : i * 64 + 2] = 90
    img[:2, :] += 15
    img += grain(rng, (h, w), 5.0, 0.5)
    return make_texture("kerb", to_u8(img), True, (texel_m, texel_m), min_size=1)
