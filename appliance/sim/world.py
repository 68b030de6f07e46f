"""Geometry of the simulated world: textured planar quads, boxes and rigid bodies.

World frame: x, y on the road surface (z = 0), z up; metres. A *face* is a planar
quad with a texture frame: the level-0 texel (a, b) of its texture lies at
``origin + a * texel_u * eu + b * texel_v * ev`` (texel centres at integer
coordinates, as OpenCV's pixel centres). Faces are one-sided (the renderer
culls a face whose ``normal`` points away from the camera) unless
``two_sided``.

Layers fix the drawing order of everything that lies on the road (which never
hides anything standing on it): the ground plane, then raised surfaces
(sidewalks, kerbs), then road markings; upright faces come last and are
depth-tested against each other.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from appliance.sim.textures import Texture

FloatArray = NDArray[np.float64]


class Layer(IntEnum):
    GROUND = 0  # the road plane
    SURFACE = 1  # sidewalk tops and kerbs
    DECAL = 2  # flat-coloured road markings
    UPRIGHT = 3  # buildings, cars, poles, movers (depth-tested)


FLAT = -1  # texture index of a flat-coloured face


@dataclass(frozen=True)
class Quad:
    """One planar face (see the module docstring). ``corners`` (4, 3) in order around the quad."""

    corners: FloatArray
    normal: FloatArray
    origin: FloatArray
    eu: FloatArray
    ev: FloatArray
    texel_m: tuple[float, float]
    texture: int
    layer: Layer
    obj: int = 0
    value: float = 0.0
    two_sided: bool = False


@dataclass(frozen=True)
class FaceSet:
    """Many quads as arrays (struct of arrays), so culling is vectorised.

    corners (F, 4, 3); normal, origin, eu, ev (F, 3); texel (F, 2) m;
    texture, layer, obj (F,) int; value (F,) float; two_sided (F,) bool.
    """

    corners: FloatArray
    normal: FloatArray
    origin: FloatArray
    eu: FloatArray
    ev: FloatArray
    texel: FloatArray
    texture: NDArray[np.int64]
    layer: NDArray[np.int64]
    obj: NDArray[np.int64]
    value: FloatArray
    two_sided: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.corners.shape[0])

    @staticmethod
    def from_quads(quads: Sequence[Quad]) -> FaceSet:
        if not quads:
            return FaceSet.empty()
        return FaceSet(
            corners=np.array([q.corners for q in quads], dtype=np.float64).reshape(-1, 4, 3),
            normal=np.array([q.normal for q in quads], dtype=np.float64),
            origin=np.array([q.origin for q in quads], dtype=np.float64),
            eu=np.array([q.eu for q in quads], dtype=np.float64),
            ev=np.array([q.ev for q in quads], dtype=np.float64),
            texel=np.array([q.texel_m for q in quads], dtype=np.float64),
            texture=np.array([q.texture for q in quads], dtype=np.int64),
            layer=np.array([int(q.layer) for q in quads], dtype=np.int64),
            obj=np.array([q.obj for q in quads], dtype=np.int64),
            value=np.array([q.value for q in quads], dtype=np.float64),
            two_sided=np.array([q.two_sided for q in quads], dtype=bool),
        )

    @staticmethod
    def empty() -> FaceSet:
        z3 = np.zeros((0, 3))
        zi = np.zeros(0, np.int64)
        return FaceSet(
            np.zeros((0, 4, 3)),
            z3,
            z3,
            z3,
            z3,
            np.zeros((0, 2)),
            zi,
            zi,
            zi,
            np.zeros(0),
            np.zeros(0, bool),
        )

    @staticmethod
    def concat(sets: Sequence[FaceSet]) -> FaceSet:
        sets = [s for s in sets if len(s)]
        if not sets:
            return FaceSet.empty()
        return FaceSet(*(np.concatenate([getattr(s, f) for s in sets]) for f in _FIELDS))

    def transformed(self, R: FloatArray, t: FloatArray) -> FaceSet:
        """The faces moved rigidly: ``X' = R X + t`` (e.g. body frame -> world)."""
        return FaceSet(
            corners=self.corners @ R.T + t,
            normal=self.normal @ R.T,
            origin=self.origin @ R.T + t,
            eu=self.eu @ R.T,
            ev=self.ev @ R.T,
            texel=self.texel,
            texture=self.texture,
            layer=self.layer,
            obj=self.obj,
            value=self.value,
            two_sided=self.two_sided,
        )


_FIELDS = (
    "corners",
    "normal",
    "origin",
    "eu",
    "ev",
    "texel",
    "texture",
    "layer",
    "obj",
    "value",
    "two_sided",
)


def rect_face(
    center: FloatArray,
    normal: FloatArray,
    ev: FloatArray,
    width: float,
    height: float,
    texture: int,
    textures: Sequence[Texture],
    layer: Layer = Layer.UPRIGHT,
    obj: int = 0,
    u_offset_m: float = 0.0,
    value: float = 0.0,
) -> Quad:
    """A width x height rectangle centred at ``center``, seen from the side ``normal`` points to.

    ``ev`` is the texture's down (row) direction in the face; ``eu = normal x ev``
    (image right when looking at the face). A wrapping texture keeps its own texel
    size (shifted by ``u_offset_m`` along eu); a stretched texture is scaled to
    cover the face exactly.
    """
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    ev = np.asarray(ev, float) / np.linalg.norm(ev)
    eu = np.cross(n, ev)
    c = np.asarray(center, float)
    hw, hh = width / 2.0, height / 2.0
    corners = np.array(
        [c - hw * eu - hh * ev, c + hw * eu - hh * ev, c + hw * eu + hh * ev, c - hw * eu + hh * ev]
    )
    if texture == FLAT:
        su = sv = 1.0
        origin = corners[0]
    elif textures[texture].wrap:
        su, sv = textures[texture].texel_m
        origin = corners[0] - u_offset_m * eu
    else:
        th, tw = textures[texture].shape
        su, sv = width / tw, height / th
        origin = corners[0] + 0.5 * su * eu + 0.5 * sv * ev
    return Quad(corners, n, origin, eu, ev, (su, sv), texture, layer, obj, value)


@dataclass(frozen=True)
class BoxSkin:
    """Texture indices of a box's faces (or ``FLAT``): front (+x), rear, left (+y), right, top."""

    front: int
    rear: int
    left: int
    right: int
    top: int


def box_faces(
    length: float, width: float, height: float, skin: BoxSkin, textures: Sequence[Texture], obj: int
) -> FaceSet:
    """The five visible faces of a box in its body frame.

    Body frame: origin at the centre of the footprint on the ground, x forward
    (length), y left (width), z up (height). No bottom face.
    """
    L, W, Hh = length / 2.0, width / 2.0, height / 2.0
    down = np.array([0.0, 0.0, -1.0])
    quads = [
        rect_face(
            np.array([L, 0, Hh]),
            np.array([1.0, 0, 0]),
            down,
            width,
            height,
            skin.front,
            textures,
            obj=obj,
        ),
        rect_face(
            np.array([-L, 0, Hh]),
            np.array([-1.0, 0, 0]),
            down,
            width,
            height,
            skin.rear,
            textures,
            obj=obj,
        ),
        rect_face(
            np.array([0, W, Hh]),
            np.array([0, 1.0, 0]),
            down,
            length,
            height,
            skin.left,
            textures,
            obj=obj,
        ),
        rect_face(
            np.array([0, -W, Hh]),
            np.array([0, -1.0, 0]),
            down,
            length,
            height,
            skin.right,
            textures,
            obj=obj,
        ),
        rect_face(
            np.array([0, 0, height]),
            np.array([0, 0, 1.0]),
            np.array([-1.0, 0, 0]),
            width,
            length,
            skin.top,
            textures,
            obj=obj,
        ),
    ]
    return FaceSet.from_quads(quads)


def yaw_matrix(yaw: float) -> FloatArray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Body:
    """A rigid box: id, class, size (length, width, height) m and faces in its body frame."""

    obj: int
    kind: str
    size: tuple[float, float, float]
    faces: FaceSet

    def corners(self, x: float, y: float, yaw: float) -> FloatArray:
        """The 8 world corners (8, 3) of the box standing at (x, y) with heading ``yaw``."""
        L, W, Hh = self.size[0] / 2.0, self.size[1] / 2.0, self.size[2]
        local = np.array(
            [[sx * L, sy * W, z] for z in (0.0, Hh) for sx in (1, -1) for sy in (1, -1)]
        )
        out: FloatArray = local @ yaw_matrix(yaw).T + np.array([x, y, 0.0])
        return out

    def placed(self, x: float, y: float, yaw: float) -> FaceSet:
        return self.faces.transformed(yaw_matrix(yaw), np.array([x, y, 0.0]))


@dataclass(frozen=True)
class StaticObject:
    """A body placed in the world for the whole drive (parked car, building, pole)."""

    body: Body
    x: float
    y: float
    yaw: float
