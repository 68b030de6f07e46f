"""Layout of the simulated town street: its cross-section, the plan a scenario fixes, and
the ego path as the street's centre line.

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

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.sim.ego import EgoPath

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
class Overhead:
    """A structure across the street above the road at arc length ``s`` (m), its lowest edge
    ``clearance_m`` over the road: ``kind`` "sign" (a gantry: two posts on the sidewalks, a beam
    and a direction sign over each lane) or "bridge" (a concrete deck on two walls beyond the
    sidewalks)."""

    s: float
    kind: str = "sign"
    clearance_m: float = 5.0

    def __post_init__(self) -> None:
        if self.kind not in ("sign", "bridge"):
            raise ValueError(f"unknown overhead structure {self.kind!r}")


@dataclass(frozen=True)
class StreetPlan:
    """What a scenario fixes about the street; the rest is drawn from the seed."""

    intersections: tuple[Intersection, ...] = ()
    parked: tuple[ParkedCar, ...] = ()
    clear_view: tuple[ClearView, ...] = ()
    parking_occupancy: float = 0.55
    overhead: tuple[Overhead, ...] = ()


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


def subtract(
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
