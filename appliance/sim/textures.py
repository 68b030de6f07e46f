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


def _wrapped(draw: Callable[[int, int], None], w: int, h: int) -> None:
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


def _to_u8(img: NDArray[Any]) -> U8:
    out: U8 = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return out


def _grain(rng: np.random.Generator, shape: tuple[int, int], amp: float, blur: float = 0.6) -> F32:
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

        _wrapped(draw, size, size)
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

        _wrapped(draw_c, size, size)
    img += cracks
    img += _grain(rng, shape, 7.0, 0.7)
    img += 10.0 * (rng.random(shape) < 0.004)  # bright chippings
    img = blur_wrap(img.astype(np.float32), 0.6)
    return make_texture("asphalt", _to_u8(img), True, (texel_m, texel_m))


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

            _wrapped(draw, size, size)
    img += 6.0 * pink_noise(rng, shape, beta=1.0, low_cut=2.0)
    img += _grain(rng, shape, 6.0, 0.8)
    for j in range(n):  # joints
        img[j * slab : j * slab + 2, :] = base - 55
        shift = (slab // 2) * (j % 2)
        for i in range(n + 1):
            x = (i * slab + shift) % size
            img[j * slab : (j + 1) * slab, x : x + 2] = base - 55
    img = blur_wrap(img, 0.7)
    return make_texture("paving", _to_u8(img), True, (texel_m, texel_m))


def kerb(rng: np.random.Generator, texel_m: float = 0.015625) -> Texture:
    """Kerb stones 1 m long (64 texels) with joints, 8 texels tall; wraps."""
    w, h = 256, 8
    img = np.zeros((h, w), np.float32)
    for i in range(4):
        img[:, i * 64 : (i + 1) * 64] = float(rng.uniform(165, 200))
        img[:, i * 64 : i * 64 + 2] = 90
    img[:2, :] += 15
    img += _grain(rng, (h, w), 5.0, 0.5)
    return make_texture("kerb", _to_u8(img), True, (texel_m, texel_m), min_size=1)


# ---------------------------------------------------------------- buildings


def facade(rng: np.random.Generator, index: int, texel_m: float = 0.02) -> Texture:
    """One floor (3.2 m) and two window bays (2 x 2.56 m) of a facade; wraps.

    Styles: plaster, brick, or a glass grid; windows with frames, sills and
    reflections.
    """
    w, h = 256, 160
    style = index % 3
    wall = float(rng.uniform(110, 200))
    img = np.full((h, w), wall, np.float32)
    if style == 1:  # bricks, 16 x 4 texels (0.32 x 0.08 m)
        for r in range(h // 4):
            off = 8 * (r % 2)
            for c in range(w // 16 + 1):
                val = wall + float(rng.normal(0, 10))
                x0 = (c * 16 + off) % w

                def draw(dx: int, dy: int, x0: int = x0, r: int = r, val: float = val) -> None:
                    cv2.rectangle(
                        img, (x0 + dx, r * 4 + dy), (x0 + 14 + dx, r * 4 + 2 + dy), val, -1
                    )

                _wrapped(draw, w, h)
        img[3::4, :] = wall - 40
    img += 8.0 * pink_noise(rng, (h, w), beta=1.2, low_cut=1.0)
    win_w = int(rng.integers(50, 76)) if style != 2 else 110
    win_h = int(rng.integers(60, 86)) if style != 2 else 120
    top = int(rng.integers(30, 50)) if style != 2 else 20
    glass = float(rng.uniform(30, 70))
    frame = float(np.clip(wall + rng.choice([-70.0, 50.0]), 20, 240))
    for bay in range(2):
        x0 = bay * 128 + (128 - win_w) // 2
        cv2.rectangle(img, (x0 - 4, top - 4), (x0 + win_w + 3, top + win_h + 3), frame, -1)
        refl = np.linspace(0, 1, win_h, dtype=np.float32)[:, None] * float(rng.uniform(10, 40))
        pane = glass + refl + 6.0 * pink_noise(rng, (win_h, win_w), beta=1.5, low_cut=1.0)
        img[top : top + win_h, x0 : x0 + win_w] = pane
        mid = x0 + win_w // 2
        cv2.line(img, (mid, top), (mid, top + win_h - 1), frame, 3)  # mullion
        cv2.line(
            img, (x0, top + win_h // 3), (x0 + win_w - 1, top + win_h // 3), frame, 2
        )  # transom
        cv2.rectangle(
            img,
            (x0 - 8, top + win_h + 4),
            (x0 + win_w + 7, top + win_h + 9),
            float(np.clip(wall + 40, 0, 255)),
            -1,
        )  # sill
        if rng.random() < 0.5:  # curtain
            cw = int(rng.integers(10, win_w // 2))
            img[top : top + win_h, x0 : x0 + cw] = float(rng.uniform(120, 220))
    if style == 2:
        img[:, ::64] = frame
    cv2.line(img, (0, h - 2), (w - 1, h - 2), wall - 30, 2)  # floor band
    img += _grain(rng, (h, w), 4.0, 0.6)
    img = blur_wrap(img, 0.6)
    return make_texture(f"facade{index}", _to_u8(img), True, (texel_m, texel_m))


def roof(rng: np.random.Generator) -> Texture:
    img = 70.0 + 15.0 * pink_noise(rng, (128, 128), beta=1.0, low_cut=1.0)
    return make_texture("roof", _to_u8(img), True, (0.05, 0.05))


# ---------------------------------------------------------------- vehicles, people, poles


def car_side(rng: np.random.Generator, body: float) -> U8:
    """Side of a car, 256 x 84 texels (front to the right), stretched onto the box side."""
    w, h = 256, 84
    img = np.full((h, w), body, np.float32)
    img[: int(h * 0.42)] = body - 12.0  # roof pillars and cabin (the box is the car's outline)
    glass = np.array([[50, 33], [74, 9], [170, 9], [205, 33]], np.int32)
    cv2.fillConvexPoly(img, glass, float(rng.uniform(25, 60)))
    cv2.line(img, (122, 8), (122, 34), body, 5)  # B pillar
    cv2.line(img, (90, 36), (90, 70), body - 35, 1)  # door gaps
    cv2.line(img, (160, 36), (160, 70), body - 35, 1)
    cv2.rectangle(img, (100, 44), (110, 46), body + 40, -1)  # handles
    cv2.rectangle(img, (170, 44), (180, 46), body + 40, -1)
    img[int(h * 0.78) :] = body - 45  # sill / shadow
    for cx in (52, 204):
        cv2.circle(img, (cx, 70), 14, 25.0, -1)
        cv2.circle(img, (cx, 70), 7, 150.0, -1)
        cv2.circle(img, (cx, 70), 2, 60.0, -1)
    img += 4.0 * pink_noise(rng, (h, w), beta=1.0, low_cut=1.0)
    return _to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def car_end(rng: np.random.Generator, body: float, front: bool) -> U8:
    """Front or rear of a car, 96 x 80 texels."""
    w, h = 96, 80
    img = np.full((h, w), body - 12.0, np.float32)
    cv2.fillConvexPoly(
        img, np.array([[17, 32], [23, 8], [73, 8], [79, 32]], np.int32), float(rng.uniform(25, 60))
    )
    img[34:] = body
    lamp = 230.0 if front else 70.0
    cv2.rectangle(img, (4, 40), (22, 50), lamp, -1)
    cv2.rectangle(img, (74, 40), (92, 50), lamp, -1)
    if front:
        cv2.rectangle(img, (28, 44), (68, 56), 35.0, -1)
        for x in range(30, 68, 5):
            cv2.line(img, (x, 45), (x, 55), 80.0, 1)
    cv2.rectangle(img, (34, 58), (62, 66), 235.0, -1)  # number plate
    for x in range(36, 60, 5):  # characters
        cv2.rectangle(img, (x, 60), (x + 2, 64), 20.0, -1)
    img[68:] = 30.0  # bumper shadow, tyres
    img += 3.0 * pink_noise(rng, (h, w), beta=1.0, low_cut=1.0)
    return _to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def pedestrian(rng: np.random.Generator, side: bool) -> U8:
    """A person, 64 x 224 texels (front or side view), stretched onto the box face."""
    w, h = 64, 224
    bg = float(rng.uniform(90, 140))
    img = np.full((h, w), bg, np.float32)
    shirt, trousers = float(rng.uniform(30, 230)), float(rng.uniform(20, 120))
    half = 14 if side else 22
    cx = w // 2
    cv2.ellipse(img, (cx, 16), (9 if side else 11, 14), 0, 0, 360, 190.0, -1)  # head
    cv2.ellipse(img, (cx, 9), (10 if side else 12, 8), 0, 180, 360, 40.0, -1)  # hair
    cv2.rectangle(img, (cx - half, 32), (cx + half, 118), shirt, -1)
    if rng.random() < 0.5:  # stripes
        for y in range(38, 118, 10):
            cv2.line(img, (cx - half, y), (cx + half, y), 255.0 - shirt, 3)
    if not side:
        cv2.rectangle(img, (cx - half - 8, 36), (cx - half - 1, 110), shirt - 20, -1)  # arms
        cv2.rectangle(img, (cx + half + 1, 36), (cx + half + 8, 110), shirt - 20, -1)
        cv2.circle(img, (cx - half - 4, 114), 4, 190.0, -1)
        cv2.circle(img, (cx + half + 4, 114), 4, 190.0, -1)
    cv2.rectangle(img, (cx - half + 2, 118), (cx - 2, 210), trousers, -1)
    cv2.rectangle(img, (cx + 2, 118), (cx + half - 2, 210), trousers + 15, -1)
    cv2.rectangle(img, (cx - half, 210), (cx + half, 223), 25.0, -1)  # shoes
    img += _grain(rng, (h, w), 4.0, 0.6)
    return _to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def cyclist(rng: np.random.Generator, side: bool) -> U8:
    """A cyclist, side view 224 x 230 texels or front view 80 x 230."""
    h = 230
    w = 224 if side else 80
    bg = float(rng.uniform(100, 150))
    img = np.full((h, w), bg, np.float32)
    shirt = float(rng.uniform(30, 230))
    if side:
        for cx in (45, 180):
            cv2.circle(img, (cx, 185), 40, 20.0, 4)
            cv2.circle(img, (cx, 185), 4, 20.0, -1)
            for a in range(0, 180, 30):
                d = 38 * np.array([np.cos(np.radians(a)), np.sin(np.radians(a))])
                p0 = np.rint((cx, 185) - d).astype(int)
                p1 = np.rint((cx, 185) + d).astype(int)
                cv2.line(img, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), 70.0, 1)
        frame = np.array(
            [[45, 185], [100, 120], [165, 125], [180, 185], [110, 185], [100, 120]], np.int32
        )
        cv2.polylines(img, [frame], True, 230.0, 4)
        cv2.rectangle(img, (85, 40), (130, 120), shirt, -1)  # torso
        cv2.circle(img, (140, 28), 16, 190.0, -1)  # head
        cv2.ellipse(img, (140, 20), (18, 12), 0, 180, 360, 60.0, -1)  # helmet
        cv2.line(img, (125, 55), (165, 110), shirt - 30, 8)  # arm
        cv2.line(img, (100, 120), (120, 175), 40.0, 9)  # leg
    else:
        cv2.rectangle(img, (36, 110), (44, 229), 20.0, -1)  # wheel seen head-on
        cv2.rectangle(img, (20, 110), (60, 118), 200.0, -1)  # handlebar
        cv2.rectangle(img, (22, 40), (58, 120), shirt, -1)
        cv2.circle(img, (40, 26), 15, 190.0, -1)
        cv2.ellipse(img, (40, 18), (17, 11), 0, 180, 360, 60.0, -1)
        cv2.rectangle(img, (28, 120), (36, 200), 40.0, -1)
        cv2.rectangle(img, (44, 120), (52, 200), 40.0, -1)
    img += _grain(rng, (h, w), 4.0, 0.6)
    return _to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def pole(rng: np.random.Generator) -> U8:
    """Street-light pole, 16 x 256 texels: metal with bands and stickers."""
    img = np.full((256, 16), float(rng.uniform(60, 110)), np.float32)
    for y in rng.integers(20, 240, 5):
        img[int(y) : int(y) + 4] += float(rng.choice([-40.0, 60.0]))
    img[200:] -= 20
    img += _grain(rng, (256, 16), 5.0, 0.5)
    return _to_u8(img)


def sign(rng: np.random.Generator) -> U8:
    """A traffic sign plate, 64 x 64 texels."""
    img = np.full((64, 64), 230.0, np.float32)
    cv2.circle(img, (32, 32), 28, 60.0, 7)
    digit = int(rng.integers(2, 6))  # a digit-like glyph and a zero
    cv2.rectangle(img, (17, 22), (28, 42), 20.0, 2)
    cv2.line(img, (17, 32), (17 + 2 * digit, 32), 20.0, 2)
    cv2.ellipse(img, (41, 32), (6, 10), 0, 0, 360, 20.0, 2)
    return _to_u8(img)
