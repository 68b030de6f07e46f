"""The static scene: a town street along the ego path, with intersections.

Cross-section (right-hand traffic), lateral offset ``d`` (m, left +) from the
centre of the ego lane::

    houses  sidewalk   kerb  parking     ego lane    oncoming   parking   kerb  sidewalk  houses
     -7.4  -6.9..-3.9 -3.9  -3.9..-1.75 -1.75..1.75 1.75..5.25 5.25..7.4  7.4  7.4..10.4  10.9

Road markings: solid edge lines at -1.75 and 5.25, a dashed centre line at
1.75 (3 m dash, 6 m gap), a zebra crossing before each intersection. The
street follows the ego path (curves included), so the ego always drives in
its lane. Cross streets are perpendicular, 7 m wide with 3 m sidewalks; an
"open" corner has no buildings (a car park), so that traffic on the cross
street can be seen early. Building sizes, parked cars (colour, occupancy)
and poles are drawn from the seed; anything that stands on a mover's path is
left out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.sim.ego import EgoPath
from appliance.sim.materials import N_FACADES, TextureBank
from appliance.sim.world import (
    FLAT,
    Body,
    BoxSkin,
    FaceSet,
    Layer,
    Quad,
    StaticObject,
    box_faces,
    rect_face,
)

FloatArray = NDArray[np.float64]

LANE_EDGE_RIGHT, CENTRE_LINE, LANE_EDGE_LEFT = -1.75, 1.75, 5.25
PARK_RIGHT, PARK_LEFT = -2.85, 6.33
KERB_RIGHT, KERB_LEFT = -3.9, 7.4
SIDEWALK_W, KERB_H = 3.0, 0.12
FRONT_RIGHT, FRONT_LEFT = -7.4, 10.9
CROSS_HALF, CROSS_SIDEWALK = 3.5, 3.0
PAINT = 215.0
KERB_GRAY = 182.0
FLOOR_M = 3.2


@dataclass(frozen=True)
class Intersection:
    """A perpendicular cross street whose centre line meets the ego path at arc length ``s`` (m).

    ``open_corners``: any of "near_right", "near_left", "far_right", "far_left";
    no buildings within ``open_length_m`` of the crossing there.
    """

    s: float
    open_corners: tuple[str, ...] = ()
    open_length_m: float = 45.0


@dataclass(frozen=True)
class ParkedCar:
    """A parked car the scenario needs (e.g. the one a pedestrian steps out behind).

    ``s``: centre along the path (m); ``side``: "right" or "left"; ``length_m``.
    """

    s: float
    side: str = "right"
    length_m: float = 4.5
    skin: int = 0


@dataclass(frozen=True)
class ClearView:
    """No random parked cars or poles on ``side`` between arc lengths ``s_from`` and ``s_to`` (m),
    where they would hide a mover from the camera."""

    s_from: float
    s_to: float
    side: str = "right"


@dataclass(frozen=True)
class StreetPlan:
    """What a scenario fixes about the street; the rest is drawn from the seed."""

    intersections: tuple[Intersection, ...] = ()
    parked: tuple[ParkedCar, ...] = ()
    clear_view: tuple[ClearView, ...] = ()
    parking_occupancy: float = 0.55


@dataclass(frozen=True)
class KeepClear:
    """Points (N, 2) on movers' paths (world, m) and the clearance (m) around them."""

    points: FloatArray
    radius: float


class Centreline:
    """The ego lane's centre line as a function of arc length s (straight beyond the path)."""

    def __init__(self, path: EgoPath) -> None:
        self.s, self.x, self.y, self.psi = path.s, path.x, path.y, path.psi

    def pose(self, s: FloatArray | float) -> tuple[FloatArray, FloatArray, FloatArray]:
        s = np.asarray(s, float)
        x, y = np.interp(s, self.s, self.x), np.interp(s, self.s, self.y)
        psi = np.interp(s, self.s, self.psi)
        for end, sign in ((0, -1.0), (-1, 1.0)):
            beyond = np.maximum(sign * (s - self.s[end]), 0.0)
            x = x + sign * beyond * np.cos(self.psi[end])
            y = y + sign * beyond * np.sin(self.psi[end])
        return x, y, psi

    def point(self, s: float, d: float, z: float = 0.0) -> FloatArray:
        x, y, psi = self.pose(s)
        return np.array([float(x) - d * np.sin(psi), float(y) + d * np.cos(psi), z])

    def frame(self, s: float) -> tuple[FloatArray, FloatArray]:
        """Unit tangent and left normal (3-vectors) at s."""
        _, _, psi = self.pose(s)
        c, sn = float(np.cos(psi)), float(np.sin(psi))
        return np.array([c, sn, 0.0]), np.array([-sn, c, 0.0])

    def chunks(
        self, s_a: float, s_b: float, max_len: float = 20.0, max_turn: float = np.radians(2.0)
    ) -> list[tuple[float, float]]:
        """Split [s_a, s_b] into pieces short enough to be straight."""
        grid = np.arange(s_a, s_b, 0.5).tolist() + [s_b]
        _, _, psi = self.pose(np.array(grid))
        out, start = [], 0
        for k in range(1, len(grid)):
            if (
                grid[k] - grid[start] >= max_len
                or abs(psi[k] - psi[start]) > max_turn
                or k == len(grid) - 1
            ):
                out.append((grid[start], grid[k]))
                start = k
        return out


def _subtract(
    intervals: list[tuple[float, float]], cut: tuple[float, float]
) -> list[tuple[float, float]]:
    out = []
    for a, b in intervals:
        if cut[1] <= a or cut[0] >= b:
            out.append((a, b))
            continue
        if a < cut[0]:
            out.append((a, cut[0]))
        if cut[1] < b:
            out.append((cut[1], b))
    return out


def _ground_quad(
    corners: FloatArray,
    eu: FloatArray,
    texture: int,
    bank: TextureBank,
    layer: Layer,
    u_offset: float = 0.0,
    value: float = 0.0,
    normal: FloatArray | None = None,
    ev: FloatArray | None = None,
) -> Quad:
    """A quad with texture axis eu (and ev = normal x eu... chosen so that eu x ev = -normal)."""
    n = np.array([0.0, 0.0, 1.0]) if normal is None else normal
    if ev is None:
        ev = np.cross(eu, n)  # so that eu = n x ev
    su, sv = bank.textures[texture].texel_m if texture != FLAT else (1.0, 1.0)
    return Quad(
        np.asarray(corners, float),
        n,
        corners[0] - u_offset * eu,
        eu,
        ev,
        (su, sv),
        texture,
        layer,
        0,
        value,
    )


class StreetBuilder:
    """Builds the static faces and objects of one drive (see the module docstring)."""

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
        self.quads: list[Quad] = []
        self.objects: list[StaticObject] = []
        self.next_id = {"car": 101, "building": 1001, "pole": 3001}

    def _id(self, kind: str) -> int:
        self.next_id[kind] += 1
        return self.next_id[kind] - 1

    def build(self, s_lo: float, s_hi: float) -> tuple[FaceSet, list[StaticObject]]:
        self._sidewalks(s_lo, s_hi)
        self._markings(s_lo, s_hi)
        self._buildings(s_lo, s_hi)
        self._parked_cars(s_lo, s_hi)
        self._poles(s_lo, s_hi)
        for x in self.plan.intersections:
            self._cross_street(x)
        faces = FaceSet.concat(
            [FaceSet.from_quads(self.quads)]
            + [o.body.placed(o.x, o.y, o.yaw) for o in self.objects]
        )
        return faces, self.objects

    # ------------------------------------------------------------ road level

    def _strip(
        self,
        s_a: float,
        s_b: float,
        d_a: float,
        d_b: float,
        z: float,
        texture: int,
        layer: Layer,
        value: float = 0.0,
    ) -> None:
        L = self.line
        c = np.array(
            [L.point(s_a, d_a, z), L.point(s_b, d_a, z), L.point(s_b, d_b, z), L.point(s_a, d_b, z)]
        )
        eu, _ = L.frame(s_a)
        self.quads.append(_ground_quad(c, eu, texture, self.bank, layer, s_a, value))

    def _kerb(self, s_a: float, s_b: float, d: float, facing_left: bool) -> None:
        L = self.line
        c = np.array(
            [
                L.point(s_a, d, KERB_H),
                L.point(s_b, d, KERB_H),
                L.point(s_b, d, 0.0),
                L.point(s_a, d, 0.0),
            ]
        )
        tan, left = L.frame(s_a)
        n = left if facing_left else -left
        ev = np.array([0.0, 0.0, -1.0])
        eu = np.cross(n, ev)
        self.quads.append(
            Quad(c, n, c[0], eu, ev, (1.0, 1.0), FLAT, Layer.SURFACE, value=KERB_GRAY)
        )

    def _main_intervals(self, s_lo: float, s_hi: float, half: float) -> list[tuple[float, float]]:
        iv = [(s_lo, s_hi)]
        for x in self.plan.intersections:
            iv = _subtract(iv, (x.s - half, x.s + half))
        return iv

    def _sidewalks(self, s_lo: float, s_hi: float) -> None:
        pav = self.bank["paving"]
        for a, b in self._main_intervals(s_lo, s_hi, CROSS_HALF):
            for s_a, s_b in self.line.chunks(a, b):
                self._strip(
                    s_a, s_b, KERB_RIGHT, KERB_RIGHT - SIDEWALK_W, KERB_H, pav, Layer.SURFACE
                )
                self._strip(s_a, s_b, KERB_LEFT, KERB_LEFT + SIDEWALK_W, KERB_H, pav, Layer.SURFACE)
                self._kerb(s_a, s_b, KERB_RIGHT, True)
                self._kerb(s_a, s_b, KERB_LEFT, False)

    def _markings(self, s_lo: float, s_hi: float) -> None:
        for a, b in self._main_intervals(s_lo, s_hi, CROSS_HALF):
            for s_a, s_b in self.line.chunks(a, b):
                for d in (LANE_EDGE_RIGHT, LANE_EDGE_LEFT):
                    self._strip(s_a, s_b, d - 0.075, d + 0.075, 0.0, FLAT, Layer.DECAL, PAINT)
        dash_cut = [(x.s - 13.0, x.s + CROSS_HALF + 1.0) for x in self.plan.intersections]
        s = np.floor(s_lo / 9.0) * 9.0
        while s < s_hi:
            if not any(c[0] < s + 3.0 and s < c[1] for c in dash_cut):
                self._strip(
                    s,
                    s + 3.0,
                    CENTRE_LINE - 0.06,
                    CENTRE_LINE + 0.06,
                    0.0,
                    FLAT,
                    Layer.DECAL,
                    PAINT,
                )
            s += 9.0
        for x in self.plan.intersections:  # zebra crossing
            for d in np.arange(LANE_EDGE_RIGHT + 0.25, LANE_EDGE_LEFT - 0.2, 1.0):
                self._strip(
                    x.s - 10.0, x.s - 7.0, float(d), float(d) + 0.5, 0.0, FLAT, Layer.DECAL, PAINT
                )

    # ------------------------------------------------------------ objects

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

    def _buildings(self, s_lo: float, s_hi: float) -> None:
        for side, front, sign in (("right", FRONT_RIGHT, -1.0), ("left", FRONT_LEFT, 1.0)):
            iv = [(s_lo, s_hi)]
            for x in self.plan.intersections:
                lo = x.s - CROSS_HALF - CROSS_SIDEWALK - 0.5
                hi = x.s + CROSS_HALF + CROSS_SIDEWALK + 0.5
                if f"near_{side}" in x.open_corners:
                    lo = x.s - x.open_length_m
                if f"far_{side}" in x.open_corners:
                    hi = x.s + x.open_length_m
                iv = _subtract(iv, (lo, hi))

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

    def _parked_cars(self, s_lo: float, s_hi: float) -> None:
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
                iv = _subtract(iv, (x.s - 13.0, x.s + 9.0))
            for zone in self.plan.clear_view:
                if zone.side == side:
                    iv = _subtract(iv, (zone.s_from, zone.s_to))
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

    def _poles(self, s_lo: float, s_hi: float) -> None:
        pole, sign, roof = self.bank["pole"], self.bank["sign"], self.bank["roof"]
        pole_skin = BoxSkin(pole, pole, pole, pole, roof)
        sign_skin = BoxSkin(sign, sign, sign, sign, roof)
        for side, d in (("right", KERB_RIGHT - 0.5), ("left", KERB_LEFT + 0.5)):
            iv = self._main_intervals(s_lo, s_hi, CROSS_HALF + 4.0)
            for zone in self.plan.clear_view:
                if zone.side == side:
                    iv = _subtract(iv, (zone.s_from, zone.s_to))
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

    # ------------------------------------------------------------ cross streets

    def _cross_street(self, x: Intersection) -> None:
        L = self.line
        tan, left = L.frame(x.s)
        o = L.point(x.s, 0.0)
        far_d = 150.0

        def pt(e: float, d: float, z: float = 0.0) -> FloatArray:
            out: FloatArray = o + e * tan + d * left + np.array([0.0, 0.0, z])
            return out

        pav = self.bank["paving"]
        for d0, d1 in ((KERB_RIGHT, -far_d), (KERB_LEFT, far_d)):
            for e_in, e_out in (
                (-CROSS_HALF, -CROSS_HALF - CROSS_SIDEWALK),
                (CROSS_HALF, CROSS_HALF + CROSS_SIDEWALK),
            ):
                c = np.array(
                    [
                        pt(e_in, d0, KERB_H),
                        pt(e_in, d1, KERB_H),
                        pt(e_out, d1, KERB_H),
                        pt(e_out, d0, KERB_H),
                    ]
                )
                self.quads.append(_ground_quad(c, left, pav, self.bank, Layer.SURFACE))
                n = -tan if e_in > 0 else tan  # the kerb faces the cross road
                ev = np.array([0.0, 0.0, -1.0])
                eu = np.cross(n, ev)
                k = np.array(
                    [pt(e_in, d0, KERB_H), pt(e_in, d1, KERB_H), pt(e_in, d1), pt(e_in, d0)]
                )
                self.quads.append(
                    Quad(k, n, k[0], eu, ev, (1.0, 1.0), FLAT, Layer.SURFACE, value=KERB_GRAY)
                )
            sgn = np.sign(d1)
            for d in np.arange(abs(d0) + 3.0, far_d, 9.0):
                c = np.array(
                    [
                        pt(-0.06, sgn * d),
                        pt(-0.06, sgn * (d + 3)),
                        pt(0.06, sgn * (d + 3)),
                        pt(0.06, sgn * d),
                    ]
                )
                self.quads.append(_ground_quad(c, left, FLAT, self.bank, Layer.DECAL, value=PAINT))
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
