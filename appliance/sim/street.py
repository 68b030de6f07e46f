"""The static scene of a drive: the road surface, sidewalks, kerbs and markings along the ego
path (and across each cross street), plus the roadside objects of :mod:`appliance.sim.roadside`.
The layout and the plan types live in :mod:`appliance.sim.layout` (re-exported here).
"""

from __future__ import annotations

import numpy as np

from appliance.sim.layout import (
    CENTRE_LINE,
    CROSS_HALF,
    CROSS_SIDEWALK,
    KERB_GRAY,
    KERB_H,
    KERB_LEFT,
    KERB_RIGHT,
    LANE_EDGE_LEFT,
    LANE_EDGE_RIGHT,
    PAINT,
    SIDEWALK_W,
    Centreline,
    ClearView,
    FloatArray,
    Intersection,
    KeepClear,
    Overhead,
    ParkedCar,
    StreetPlan,
    subtract,
)
from appliance.sim.materials import TextureBank
from appliance.sim.roadside import Roadside
from appliance.sim.world import FLAT, FaceSet, Layer, Quad, StaticObject

__all__ = [
    "Centreline",
    "ClearView",
    "Intersection",
    "KeepClear",
    "Overhead",
    "ParkedCar",
    "StreetBuilder",
    "StreetPlan",
]


ROAD_TURN_DEG = 8.0  # a road strip turns at most this much (texture axes within 4 deg of the road)


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
        self.roadside = Roadside(plan, line, bank, rng, keep_clear)

    def build(self, s_lo: float, s_hi: float) -> tuple[FaceSet, list[StaticObject]]:
        self._road(s_lo, s_hi)
        self._sidewalks(s_lo, s_hi)
        self._markings(s_lo, s_hi)
        self.roadside.buildings(s_lo, s_hi)
        self.roadside.parked_cars(s_lo, s_hi)
        self.roadside.poles(s_lo, s_hi)
        for x in self.plan.intersections:
            self._cross_street(x)
            self.roadside.cross_street_buildings(x)
        for o in self.plan.overhead:
            self.roadside.overhead(o)
        objects = self.roadside.objects
        faces = FaceSet.concat(
            [FaceSet.from_quads(self.quads)] + [o.body.placed(o.x, o.y, o.yaw) for o in objects]
        )
        return faces, objects

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
        _, left = L.frame(s_a)
        n = left if facing_left else -left
        ev = np.array([0.0, 0.0, -1.0])
        eu = np.cross(n, ev)
        self.quads.append(
            Quad(c, n, c[0], eu, ev, (1.0, 1.0), FLAT, Layer.SURFACE, value=KERB_GRAY)
        )

    def _main_intervals(self, s_lo: float, s_hi: float, half: float) -> list[tuple[float, float]]:
        iv = [(s_lo, s_hi)]
        for x in self.plan.intersections:
            iv = subtract(iv, (x.s - half, x.s + half))
        return iv

    def _road(self, s_lo: float, s_hi: float) -> None:
        """The carriageway's asphalt in strips whose texture axes follow the road.

        The ground plane under everything has world-fixed texture axes; a road seen at a
        grazing angle diagonally to them (a bend) would get the rip-map level of the bounding
        box of its pixel footprint along both axes, blurring the asphalt across the road into
        streaks a real camera does not see. Strips run 1 m under each sidewalk, so a chunk's
        chord never leaves a gap at a kerb."""
        asphalt = self.bank["asphalt"]
        for a, b in self._main_intervals(s_lo, s_hi, CROSS_HALF):
            for s_a, s_b in self.line.chunks(a, b, max_turn=np.radians(ROAD_TURN_DEG)):
                self._strip(s_a, s_b, KERB_RIGHT - 1.0, KERB_LEFT + 1.0, 0.0, asphalt, Layer.GROUND)

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
