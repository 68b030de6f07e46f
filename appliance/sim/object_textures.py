"""Procedural textures of the things in the street: facades, roofs, cars, people, cyclists,
poles and signs, the things on the road (a crate, a manhole cover, a painted arrow, a speed
bump) and the things above it (a direction sign on a gantry, a concrete bridge) (see
:mod:`appliance.sim.textures` for the rip-maps and the ground).

Facades wrap (one floor and two window bays repeat); the others are stretched over
the box face they skin. All are drawn from a seeded generator.
"""

from __future__ import annotations

import cv2
import numpy as np

from appliance.sim.textures import (
    U8,
    Texture,
    blur_wrap,
    grain,
    make_texture,
    pink_noise,
    to_u8,
    wrapped_draw,
)

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

                wrapped_draw(draw, w, h)
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
    img += grain(rng, (h, w), 4.0, 0.6)
    img = blur_wrap(img, 0.6)
    return make_texture(f"facade{index}", to_u8(img), True, (texel_m, texel_m))


def roof(rng: np.random.Generator) -> Texture:
    img = 70.0 + 15.0 * pink_noise(rng, (128, 128), beta=1.0, low_cut=1.0)
    return make_texture("roof", to_u8(img), True, (0.05, 0.05))


# ---------------------------------------------------------------- vehicles, people, poles


def car_side(rng: np.random.Generator, body: float, plain: bool = False) -> U8:
    """Side of a car, 256 x 84 texels (front to the right), stretched onto the box side.

    ``plain``: nearly flat paint: tinted glass, door gaps, handles and rims within a few
    levels of the body, little grain (a dark car with dark glass, a clean one-colour van)."""
    w, h = 256, 84
    detail = 0.25 if plain else 1.0  # contrast of the details against the paint
    img = np.full((h, w), body, np.float32)
    img[: int(h * 0.42)] = body - 12.0 * detail  # pillars and cabin (the box is the outline)
    glass = np.array([[50, 33], [74, 9], [170, 9], [205, 33]], np.int32)
    tint = body + rng.uniform(-12, 12) if plain else rng.uniform(25, 60)
    cv2.fillConvexPoly(img, glass, float(tint))
    cv2.line(img, (122, 8), (122, 34), body, 5)  # B pillar
    cv2.line(img, (90, 36), (90, 70), body - 35 * detail, 1)  # door gaps
    cv2.line(img, (160, 36), (160, 70), body - 35 * detail, 1)
    cv2.rectangle(img, (100, 44), (110, 46), body + 40 * detail, -1)  # handles
    cv2.rectangle(img, (170, 44), (180, 46), body + 40 * detail, -1)
    img[int(h * 0.78) :] = body - 45 * detail  # sill / shadow
    tyre = 25.0
    for cx in (52, 204):
        cv2.circle(img, (cx, 70), 14, tyre, -1)
        cv2.circle(img, (cx, 70), 7, tyre + 125 * detail, -1)
        cv2.circle(img, (cx, 70), 2, tyre + 35 * detail, -1)
    img += (1.0 if plain else 4.0) * pink_noise(rng, (h, w), beta=1.0, low_cut=1.0)
    return to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def car_end(rng: np.random.Generator, body: float, front: bool, plain: bool = False) -> U8:
    """Front or rear of a car, 96 x 80 texels (``plain``: see :func:`car_side`; the number
    plate stays)."""
    w, h = 96, 80
    img = np.full((h, w), body - (3.0 if plain else 12.0), np.float32)
    tint = body + rng.uniform(-12, 12) if plain else rng.uniform(25, 60)
    cv2.fillConvexPoly(
        img, np.array([[17, 32], [23, 8], [73, 8], [79, 32]], np.int32), float(tint)
    )
    img[34:] = body
    lamp = (230.0 if front else 70.0) if not plain else body + (25.0 if front else -15.0)
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
    img += (1.0 if plain else 3.0) * pink_noise(rng, (h, w), beta=1.0, low_cut=1.0)
    return to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def pedestrian(rng: np.random.Generator, side: bool, plain: bool = False) -> U8:
    """A person, 64 x 224 texels (front or side view), stretched onto the box face.

    ``plain``: clothing of one colour (shirt and trousers within a few levels of each other
    and of the surroundings the box shows around the person), no stripes, little grain."""
    w, h = 64, 224
    bg = float(rng.uniform(90, 140))
    img = np.full((h, w), bg, np.float32)
    shirt, trousers = float(rng.uniform(30, 230)), float(rng.uniform(20, 120))
    if plain:
        shirt = bg + float(rng.uniform(-15, 15))
        trousers = shirt + float(rng.uniform(-10, 10))
    half = 14 if side else 22
    cx = w // 2
    cv2.ellipse(img, (cx, 16), (9 if side else 11, 14), 0, 0, 360, 190.0, -1)  # head
    cv2.ellipse(img, (cx, 9), (10 if side else 12, 8), 0, 180, 360, 40.0, -1)  # hair
    cv2.rectangle(img, (cx - half, 32), (cx + half, 118), shirt, -1)
    if not plain and rng.random() < 0.5:  # stripes
        for y in range(38, 118, 10):
            cv2.line(img, (cx - half, y), (cx + half, y), 255.0 - shirt, 3)
    if not side:
        cv2.rectangle(img, (cx - half - 8, 36), (cx - half - 1, 110), shirt - 20, -1)  # arms
        cv2.rectangle(img, (cx + half + 1, 36), (cx + half + 8, 110), shirt - 20, -1)
        cv2.circle(img, (cx - half - 4, 114), 4, 190.0, -1)
        cv2.circle(img, (cx + half + 4, 114), 4, 190.0, -1)
    cv2.rectangle(img, (cx - half + 2, 118), (cx - 2, 210), trousers, -1)
    cv2.rectangle(img, (cx + 2, 118), (cx + half - 2, 210), trousers + (3 if plain else 15), -1)
    cv2.rectangle(img, (cx - half, 210), (cx + half, 223), 25.0, -1)  # shoes
    img += grain(rng, (h, w), 1.5 if plain else 4.0, 0.6)
    return to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def cyclist(rng: np.random.Generator, side: bool, plain: bool = False) -> U8:
    """A cyclist, side view 224 x 230 texels or front view 80 x 230 (``plain``: clothing and
    frame within a few levels of the surroundings, little grain; tyres stay dark)."""
    h = 230
    w = 224 if side else 80
    bg = float(rng.uniform(100, 150))
    img = np.full((h, w), bg, np.float32)
    shirt = float(rng.uniform(30, 230))
    if plain:
        shirt = bg + float(rng.uniform(-15, 15))
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
        cv2.polylines(img, [frame], True, bg + 20.0 if plain else 230.0, 4)
        cv2.rectangle(img, (85, 40), (130, 120), shirt, -1)  # torso
        cv2.circle(img, (140, 28), 16, 190.0, -1)  # head
        cv2.ellipse(img, (140, 20), (18, 12), 0, 180, 360, 60.0, -1)  # helmet
        cv2.line(img, (125, 55), (165, 110), shirt - (5 if plain else 30), 8)  # arm
        cv2.line(img, (100, 120), (120, 175), shirt - 5 if plain else 40.0, 9)  # leg
    else:
        cv2.rectangle(img, (36, 110), (44, 229), 20.0, -1)  # wheel seen head-on
        cv2.rectangle(img, (20, 110), (60, 118), bg + 20.0 if plain else 200.0, -1)  # handlebar
        cv2.rectangle(img, (22, 40), (58, 120), shirt, -1)
        cv2.circle(img, (40, 26), 15, 190.0, -1)
        cv2.ellipse(img, (40, 18), (17, 11), 0, 180, 360, 60.0, -1)
        legs = shirt - 5 if plain else 40.0
        cv2.rectangle(img, (28, 120), (36, 200), legs, -1)
        cv2.rectangle(img, (44, 120), (52, 200), legs, -1)
    img += grain(rng, (h, w), 1.5 if plain else 4.0, 0.6)
    return to_u8(cv2.GaussianBlur(img, (0, 0), 0.6))


def pole(rng: np.random.Generator) -> U8:
    """Street-light pole, 16 x 256 texels: metal with bands and stickers."""
    img = np.full((256, 16), float(rng.uniform(60, 110)), np.float32)
    for y in rng.integers(20, 240, 5):
        img[int(y) : int(y) + 4] += float(rng.choice([-40.0, 60.0]))
    img[200:] -= 20
    img += grain(rng, (256, 16), 5.0, 0.5)
    return to_u8(img)


def sign(rng: np.random.Generator) -> U8:
    """A traffic sign plate, 64 x 64 texels."""
    img = np.full((64, 64), 230.0, np.float32)
    cv2.circle(img, (32, 32), 28, 60.0, 7)
    digit = int(rng.integers(2, 6))  # a digit-like glyph and a zero
    cv2.rectangle(img, (17, 22), (28, 42), 20.0, 2)
    cv2.line(img, (17, 32), (17 + 2 * digit, 32), 20.0, 2)
    cv2.ellipse(img, (41, 32), (6, 10), 0, 0, 360, 20.0, 2)
    return to_u8(img)


# ---------------------------------------------------------------- things on the road


def crate(rng: np.random.Generator) -> U8:
    """A wooden crate's side, 64 x 64 texels: planks with gaps, a frame and grain."""
    img = np.full((64, 64), float(rng.uniform(90, 150)), np.float32)
    for y in range(0, 64, 16):
        img[y : y + 16] += float(rng.uniform(-15, 15))
        img[y : y + 2] -= 45.0                          # the gap between planks
    img[:, :5] -= 25.0
    img[:, -5:] -= 25.0
    img += grain(rng, (64, 64), 8.0, 0.8)
    return to_u8(img)


def manhole(rng: np.random.Generator) -> U8:
    """A manhole cover on the asphalt, 64 x 64 texels: a dark cast-iron disc with a grid."""
    img = np.full((64, 64), float(rng.uniform(70, 90)), np.float32)
    disc = np.zeros((64, 64), np.float32)
    cv2.circle(disc, (32, 32), 29, 1.0, -1)
    iron = float(rng.uniform(30, 50))
    img = img * (1.0 - disc) + iron * disc
    for k in range(8, 60, 8):
        cv2.line(img, (k, 4), (k, 60), iron + 25.0, 1)
        cv2.line(img, (4, k), (60, k), iron + 25.0, 1)
    cv2.circle(img, (32, 32), 29, iron - 15.0, 2)
    img += grain(rng, (64, 64), 5.0, 0.6)
    return to_u8(img)


def arrow(rng: np.random.Generator) -> U8:
    """A straight-ahead arrow painted on the asphalt, 32 x 128 texels (across x along)."""
    img = np.full((128, 32), float(rng.uniform(70, 90)), np.float32)
    paint = float(rng.uniform(200, 235))
    cv2.rectangle(img, (12, 40), (20, 127), paint, -1)   # the shaft, towards the car
    tip = np.array([[16, 0], [2, 44], [30, 44]], np.int32)
    cv2.fillPoly(img, [tip], paint)
    img += grain(rng, (128, 32), 6.0, 0.6)
    return to_u8(img)


def speed_bump(rng: np.random.Generator) -> U8:
    """A speed bump, 256 x 32 texels (across x along): rubber with painted bands."""
    img = np.full((32, 256), float(rng.uniform(40, 60)), np.float32)
    paint = float(rng.uniform(190, 230))
    for u in range(0, 256, 32):
        img[:, u : u + 16] = paint
    img += grain(rng, (32, 256), 6.0, 0.6)
    return to_u8(img)


# ---------------------------------------------------------------- things above the road


def direction_sign(rng: np.random.Generator) -> U8:
    """A direction sign on a gantry, 64 x 128 texels (3.4 x 1.6 m): a dark panel with a light
    border, three lines of lettering and an arrow pointing down to the lane."""
    panel = float(rng.uniform(40, 80))
    light = float(rng.uniform(200, 235))
    img = np.full((64, 128), panel, np.float32)
    cv2.rectangle(img, (2, 2), (125, 61), light, 2)
    for row in (10, 24, 38):                       # words: blocks of letters with gaps
        u = 8
        while u < 96:
            n = int(rng.integers(3, 8))
            for _ in range(n):
                if u + 4 > 96:
                    break
                cv2.rectangle(img, (u, row), (u + 3, row + 8), light, -1)
                u += 6
            u += 8
    cv2.rectangle(img, (108, 10), (114, 40), light, -1)   # the arrow's shaft and head
    cv2.fillPoly(img, [np.array([[103, 40], [119, 40], [111, 54]], np.int32)], light)
    img += grain(rng, (64, 128), 4.0, 0.6)
    return to_u8(img)


def concrete(rng: np.random.Generator) -> Texture:
    """Cast concrete, 128 x 128 texels of 2 cm (wraps): formwork joints every 1.28 m and
    weathering stains."""
    img = 135.0 + 18.0 * pink_noise(rng, (128, 128), beta=1.4, low_cut=1.0)
    img[::64] -= 30.0
    img[:, ::64] -= 20.0
    img += grain(rng, (128, 128), 5.0, 0.6)
    return make_texture("concrete", to_u8(img), True, (0.02, 0.02))
