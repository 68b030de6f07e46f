"""Things standing along the street: buildings (also along cross streets), parked cars and
poles, placed from the seed (see :mod:`appliance.sim.layout`). Anything near a mover's path or
in a scenario's clear-view zone is left out; the parked cars a scenario asks for are always
placed, and so are the structures across the street above the road (a sign gantry, a bridge).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from appliance.sim.layout import (
    CROSS_HALF,
    CROSS_SIDEWALK,
    FLOOR_M,
    FRONT_LEFT,
    FRONT_RIGHT,
    KERB_LEFT,
    KERB_RIGHT,
    PARK_LEFT,
    PARK_RIGHT,
    Centreline,
    FloatArray,
    Intersection,
    KeepClear,
    Overhead,
    StreetPlan,
    subtract,
)
from appliance.sim.materials import N_FACADES, TextureBank
from appliance.sim.world import Body, BoxSkin, FaceSet, StaticObject, box_faces, rect_face

GANTRY_POSTS = (KERB_RIGHT - 1.0, KERB_LEFT + 1.0)  # lateral offsets of a sign gantry's posts


class Roadside:
    """Places the street's objects; ``objects`` collects them (ids: cars 101.., buildings 1001..,
    poles 3001.., overhead structures 4001..)."""

    def __init__(
        self,
        plan: StreetPlan,
        line: Centreline,
        bank: TextureBank,
        rng: np.random.Generator,
        keep_clear: list[KeepClear],
    ) -> None:
        self.plan, self.line, self.bank, self.rng = plan, line, bank, rng
        self.keep_clear = keep_clear
        self.objects: list[StaticObject] = []
        self.next_id = {"car": 101, "building": 1001, "pole": 3001, "overhead": 4001}

    def _id(self, kind: str) -> int:
        self.next_id[kind] += 1
        return self.next_id[kind] - 1

    def _main_intervals(self, s_lo: float, s_hi: float, half: float) -> list[tuple[float, float]]:
        iv = [(s_lo, s_hi)]
        for x in self.plan.intersections:
            iv = subtract(iv, (x.s - half, x.s + half))
        return iv

    def _clear(self, x: float, y: float, yaw: float, length: float, width: float) -> bool:
        """True when no mover path comes near the footprint."""
        c, s = np.cos(yaw), np.sin(yaw)
        for kc in self.keep_clear:
            d = kc.points - (x, y)
            lx, ly = d @ (c, s), d @ (-s, c)
            if np.any(
                (np.abs(lx) <= length / 2 + kc.radius) & (np.abs(ly) <= width / 2 + kc.radius)
            ):
                return False
        return True

    def _add_box(
        self,
        kind: str,
        x: float,
        y: float,
        yaw: float,
        size: tuple[float, float, float],
        faces_of: BoxSkin | None,
        forced: bool = False,
    ) -> bool:
        if not forced and not self._clear(x, y, yaw, size[0], size[1]):
            return False
        obj = self._id(kind)
        if kind == "building":
            faces = self._building_faces(size, obj)
        else:
            assert faces_of is not None
            faces = box_faces(*size, faces_of, self.bank.textures, obj)
        self.objects.append(StaticObject(Body(obj, kind, size, faces), x, y, yaw))
        return True

    def _building_faces(self, size: tuple[float, float, float], obj: int) -> FaceSet:
        L, W, H = size
        tex = self.bank[f"facade{int(self.rng.integers(N_FACADES))}"]
        down = np.array([0.0, 0.0, -1.0])
        quads = []
        for c, n, width in (
            ((L / 2, 0, H / 2), (1, 0, 0), W),
            ((-L / 2, 0, H / 2), (-1, 0, 0), W),
            ((0, W / 2, H / 2), (0, 1, 0), L),
            ((0, -W / 2, H / 2), (0, -1, 0), L),
        ):
            quads.append(
                rect_face(
                    np.array(c, float),
                    np.array(n, float),
                    down,
                    width,
                    H,
                    tex,
                    self.bank.textures,
                    obj=obj,
                    u_offset_m=float(self.rng.uniform(0, 5.12)),
                )
            )
        quads.append(
            rect_face(
                np.array([0, 0, H]),
                np.array([0, 0, 1.0]),
                np.array([-1.0, 0, 0]),
                W,
                L,
                self.bank["roof"],
                self.bank.textures,
                obj=obj,
            )
        )
        return FaceSet.from_quads(quads)

    def _building_row(
        self, a: float, b: float, place: Callable[[float, float, float, float], None]
    ) -> None:
        s = a + float(self.rng.uniform(0, 3))
        while s < b:
            width = float(self.rng.uniform(8, 22))
            if s + width > b:
                break
            depth = float(self.rng.uniform(10, 16))
            height = FLOOR_M * int(self.rng.integers(2, 7))
            place(s + width / 2, width, depth, height)
            s += width + (
                float(self.rng.uniform(0, 1.5))
                if self.rng.random() > 0.15
                else float(self.rng.uniform(3, 8))
            )

    def buildings(self, s_lo: float, s_hi: float) -> None:
        for side, front, sign in (("right", FRONT_RIGHT, -1.0), ("left", FRONT_LEFT, 1.0)):
            iv = [(s_lo, s_hi)]
            for x in self.plan.intersections:
                lo = x.s - CROSS_HALF - CROSS_SIDEWALK - 0.5
                hi = x.s + CROSS_HALF + CROSS_SIDEWALK + 0.5
                if f"near_{side}" in x.open_corners:
                    lo = x.s - x.open_length_m
                if f"far_{side}" in x.open_corners:
                    hi = x.s + x.open_length_m
                iv = subtract(iv, (lo, hi))

            def place(
                sc: float,
                width: float,
                depth: float,
                height: float,
                front: float = front,
                sign: float = sign,
            ) -> None:
                p = self.line.point(sc, front + sign * depth / 2)
                _, _, psi = self.line.pose(sc)
                self._add_box(
                    "building", float(p[0]), float(p[1]), float(psi), (width, depth, height), None
                )

            for a, b in iv:
                self._building_row(a, b, place)

    def parked_cars(self, s_lo: float, s_hi: float) -> None:
        for car in self.plan.parked:
            d, flip = (PARK_RIGHT, 0.0) if car.side == "right" else (PARK_LEFT, np.pi)
            p = self.line.point(car.s, d)
            _, _, psi = self.line.pose(car.s)
            self._add_box(
                "car",
                float(p[0]),
                float(p[1]),
                float(psi) + flip,
                (car.length_m, 1.8, 1.45),
                self.bank.car_skin(car.skin),
                forced=True,
            )
        forced = [(c.s, c.side, c.length_m) for c in self.plan.parked]
        for side, d, flip in (("right", PARK_RIGHT, 0.0), ("left", PARK_LEFT, np.pi)):
            iv = self._main_intervals(s_lo, s_hi, 0.0)
            for x in self.plan.intersections:
                iv = subtract(iv, (x.s - 13.0, x.s + 9.0))
            for zone in self.plan.clear_view:
                if zone.side == side:
                    iv = subtract(iv, (zone.s_from, zone.s_to))
            for a, b in iv:
                for s in np.arange(a + 3.0, b - 3.0, 6.0):
                    if self.rng.random() > self.plan.parking_occupancy:
                        continue
                    sc = float(s + self.rng.uniform(-0.5, 0.5))
                    length = float(self.rng.uniform(4.1, 4.8))
                    if any(
                        fs == side and abs(sc - f) < (fl + length) / 2 + 0.4 for f, fs, fl in forced
                    ):
                        continue
                    p = self.line.point(sc, d + float(self.rng.uniform(-0.15, 0.15)))
                    _, _, psi = self.line.pose(sc)
                    self._add_box(
                        "car",
                        float(p[0]),
                        float(p[1]),
                        float(psi) + flip,
                        (length, 1.8, 1.45),
                        self.bank.car_skin(int(self.rng.integers(100))),
                    )

    def poles(self, s_lo: float, s_hi: float) -> None:
        pole, sign, roof = self.bank["pole"], self.bank["sign"], self.bank["roof"]
        pole_skin = BoxSkin(pole, pole, pole, pole, roof)
        sign_skin = BoxSkin(sign, sign, sign, sign, roof)
        for side, d in (("right", KERB_RIGHT - 0.5), ("left", KERB_LEFT + 0.5)):
            iv = self._main_intervals(s_lo, s_hi, CROSS_HALF + 4.0)
            for zone in self.plan.clear_view:
                if zone.side == side:
                    iv = subtract(iv, (zone.s_from, zone.s_to))
            for a, b in iv:
                s = a + float(self.rng.uniform(0, 20))
                while s < b:
                    p = self.line.point(s, d)
                    _, _, psi = self.line.pose(s)
                    if self._clear(float(p[0]), float(p[1]), 0.0, 0.2, 0.2):
                        obj = self._id("pole")
                        faces = box_faces(0.16, 0.16, 5.0, pole_skin, self.bank.textures, obj)
                        if self.rng.random() < 0.5:
                            plate = box_faces(0.04, 0.6, 0.6, sign_skin, self.bank.textures, obj)
                            faces = FaceSet.concat(
                                [faces, plate.transformed(np.eye(3), np.array([0, 0, 2.2]))]
                            )
                        self.objects.append(
                            StaticObject(
                                Body(obj, "pole", (0.16, 0.16, 5.0), faces),
                                float(p[0]),
                                float(p[1]),
                                float(psi),
                            )
                        )
                    s += float(self.rng.uniform(22, 35))

    def _slab(
        self,
        size: tuple[float, float, float],
        at: tuple[float, float, float],
        skin: BoxSkin,
        bottom: int,
        obj: int,
    ) -> FaceSet:
        """A box of ``size`` whose footprint centre is at ``at`` (body frame), with a bottom
        face: it is seen from below."""
        L, W, _ = size
        under = rect_face(np.zeros(3), np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0]),
                          W, L, bottom, self.bank.textures, obj=obj)
        faces = FaceSet.concat([box_faces(*size, skin, self.bank.textures, obj),
                                FaceSet.from_quads([under])])
        return faces.transformed(np.eye(3), np.array(at, float))

    def overhead(self, o: Overhead) -> None:
        """A sign gantry or a bridge across the street at arc length ``o.s``, its lowest edge
        ``o.clearance_m`` over the road (placed whatever the movers' paths: nothing walks
        through it; no random numbers drawn)."""
        c, obj = o.clearance_m, self._id("overhead")
        b = self.bank
        plain = b["roof"]
        if o.kind == "sign":
            post = BoxSkin(b["pole"], b["pole"], b["pole"], b["pole"], plain)
            width = GANTRY_POSTS[1] - GANTRY_POSTS[0] + 0.3
            middle = 0.5 * (GANTRY_POSTS[0] + GANTRY_POSTS[1])
            height = c + 1.9
            parts = [self._slab((0.3, 0.3, height), (0.0, d, 0.0), post, plain, obj)
                     for d in GANTRY_POSTS]
            parts.append(self._slab((0.3, width, 0.4), (0.0, middle, c + 1.4),
                                    BoxSkin(plain, plain, plain, plain, plain), plain, obj))
            sign = b["direction_sign"]
            parts.append(self._slab((0.08, 3.4, 1.6), (-0.2, 0.0, c),      # faces the ego lane
                                    BoxSkin(plain, sign, plain, plain, plain), plain, obj))
            parts.append(self._slab((0.08, 3.4, 1.6), (0.2, 3.5, c),       # the oncoming lane
                                    BoxSkin(sign, plain, plain, plain, plain), plain, obj))
            size = (0.5, width, height)
        else:
            wall = b["concrete"]
            skin = BoxSkin(wall, wall, wall, wall, plain)
            width = FRONT_LEFT - FRONT_RIGHT + 2.0
            middle = 0.5 * (FRONT_LEFT + FRONT_RIGHT)
            parts = [self._slab((9.0, width, 1.1), (0.0, middle, c), skin, wall, obj)]
            parts += [self._slab((9.0, 1.0, c), (0.0, d, 0.0), skin, wall, obj)
                      for d in (FRONT_RIGHT - 0.5, FRONT_LEFT + 0.5)]
            size = (9.0, width, c + 1.1)
        p = self.line.point(o.s, 0.0)
        _, _, psi = self.line.pose(o.s)
        self.objects.append(StaticObject(Body(obj, "overhead", size, FaceSet.concat(parts)),
                                         float(p[0]), float(p[1]), float(psi)))

    def cross_street_buildings(self, x: Intersection) -> None:
        """Rows of buildings along the cross street (none in its open corners)."""
        L = self.line
        tan, left = L.frame(x.s)
        o = L.point(x.s, 0.0)
        far_d = 150.0

        def pt(e: float, d: float) -> FloatArray:
            out: FloatArray = o + e * tan + d * left
            return out

        _, _, psi = L.pose(x.s)
        for near, e_sign in (("near", -1.0), ("far", 1.0)):
            for side, d_sign in (("right", -1.0), ("left", 1.0)):
                if f"{near}_{side}" in x.open_corners:
                    continue

                def place(
                    dc: float,
                    width: float,
                    depth: float,
                    height: float,
                    e_sign: float = e_sign,
                    d_sign: float = d_sign,
                ) -> None:
                    p = pt(e_sign * (CROSS_HALF + CROSS_SIDEWALK + 0.5 + depth / 2), d_sign * dc)
                    self._add_box(
                        "building",
                        float(p[0]),
                        float(p[1]),
                        float(psi) + np.pi / 2,
                        (width, depth, height),
                        None,
                    )

                start = abs(FRONT_RIGHT if side == "right" else FRONT_LEFT) + 17.0
                self._building_row(start, far_d, place)
