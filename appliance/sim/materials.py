"""The texture bank of one drive and the skins (per-face textures) of its boxes."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from appliance.sim import object_textures as ot
from appliance.sim import textures as tx
from appliance.sim.world import BoxSkin

N_FACADES = 6
N_CAR_SKINS = 8
N_PEOPLE = 4
# the things on the road that never move, each skinned with one texture of its own
ON_ROAD = {"box": ot.crate, "manhole": ot.manhole, "arrow": ot.arrow,
           "speed_bump": ot.speed_bump}


@dataclass
class TextureBank:
    """All textures of a drive, generated from one seed; faces refer to them by index."""

    textures: list[tx.Texture] = field(default_factory=list)
    index: dict[str, int] = field(default_factory=dict)

    def add(self, texture: tx.Texture) -> int:
        self.index[texture.name] = len(self.textures)
        self.textures.append(texture)
        return self.index[texture.name]

    def __getitem__(self, name: str) -> int:
        return self.index[name]

    @staticmethod
    def generate(rng: np.random.Generator, contrast: float = 1.0) -> TextureBank:
        """Every texture from ``rng``, its contrast scaled by ``contrast`` (see
        :func:`appliance.sim.textures.with_contrast`), with a plain skin of each mover class
        (:meth:`skin`)."""
        bank = TextureBank()
        bank.add(tx.asphalt(rng))
        bank.add(tx.paving(rng))
        bank.add(tx.kerb(rng))
        bank.add(ot.roof(rng))
        for k in range(N_FACADES):
            bank.add(ot.facade(rng, k))
        for k in range(N_CAR_SKINS):
            body = float(rng.uniform(40, 220))
            bank._add_car(rng, f"{k}", body, False)
        for k in range(N_PEOPLE):
            sub = np.random.default_rng(rng.integers(2**63))
            bank.add(tx.make_texture(f"ped_front{k}", ot.pedestrian(sub, False), False))
            sub = np.random.default_rng(rng.integers(2**63))
            bank.add(tx.make_texture(f"ped_side{k}", ot.pedestrian(sub, True), False))
        for k in range(2):
            bank.add(tx.make_texture(f"cyc_side{k}", ot.cyclist(rng, True), False))
            bank.add(tx.make_texture(f"cyc_front{k}", ot.cyclist(rng, False), False))
        bank.add(tx.make_texture("pole", ot.pole(rng), False))
        bank.add(tx.make_texture("sign", ot.sign(rng), False))
        bank._add_car(rng, "_plain", float(rng.uniform(30, 220)), True)
        sub = np.random.default_rng(rng.integers(2**63))
        bank.add(tx.make_texture("ped_front_plain", ot.pedestrian(sub, False, True), False))
        sub = np.random.default_rng(rng.integers(2**63))
        bank.add(tx.make_texture("ped_side_plain", ot.pedestrian(sub, True, True), False))
        bank.add(tx.make_texture("cyc_side_plain", ot.cyclist(rng, True, True), False))
        bank.add(tx.make_texture("cyc_front_plain", ot.cyclist(rng, False, True), False))
        # drawn last: the textures above stay what they were before these existed
        for kind, draw in ON_ROAD.items():
            bank.add(tx.make_texture(kind, draw(rng), False))
        bank.add(tx.make_texture("direction_sign", ot.direction_sign(rng), False))
        bank.add(ot.concrete(rng))
        return bank.with_contrast(contrast)

    def with_contrast(self, contrast: float) -> TextureBank:
        """The same bank with every texture's contrast scaled (see
        :func:`appliance.sim.textures.with_contrast`)."""
        if contrast == 1.0:
            return self
        return TextureBank([tx.with_contrast(t, contrast) for t in self.textures], dict(self.index))

    def _add_car(self, rng: np.random.Generator, key: str, body: float, plain: bool) -> None:
        self.add(tx.make_texture(f"car_side{key}", ot.car_side(rng, body, plain), False))
        self.add(tx.make_texture(f"car_front{key}", ot.car_end(rng, body, True, plain), False))
        self.add(tx.make_texture(f"car_rear{key}", ot.car_end(rng, body, False, plain), False))

    @staticmethod
    def for_seed(seed: int, contrast: float = 1.0) -> TextureBank:
        """The bank of a seed (the same textures in every scenario of a seed) at the drive's
        contrast; read-only."""
        return _bank(seed).with_contrast(contrast)

    # ------------------------------------------------------------ skins

    def car_skin(self, k: int | str) -> BoxSkin:
        """Skin k (any int, taken modulo the number of skins) or ``"_plain"``."""
        if isinstance(k, int):
            k = k % N_CAR_SKINS
        side = self[f"car_side{k}"]
        return BoxSkin(self[f"car_front{k}"], self[f"car_rear{k}"], side, side, self["roof"])

    def person_skin(self, k: int | str) -> BoxSkin:
        if isinstance(k, int):
            k = k % N_PEOPLE
        front, side = self[f"ped_front{k}"], self[f"ped_side{k}"]
        return BoxSkin(front, front, side, side, side)

    def cyclist_skin(self, k: int | str) -> BoxSkin:
        if isinstance(k, int):
            k = k % 2
        front, side = self[f"cyc_front{k}"], self[f"cyc_side{k}"]
        return BoxSkin(front, front, side, side, front)

    def skin(self, kind: str, k: int, plain: bool = False) -> BoxSkin:
        """The skin of mover k of class ``kind`` (``plain``: the class's plain skin)."""
        key: int | str = "_plain" if plain else k
        if kind == "car":
            return self.car_skin(key)
        if kind == "pedestrian":
            return self.person_skin(key)
        if kind == "cyclist":
            return self.cyclist_skin(key)
        if kind in ON_ROAD:                      # one texture on every face
            t = self[kind]
            return BoxSkin(t, t, t, t, t)
        raise ValueError(f"unknown mover class {kind!r}")


@lru_cache(maxsize=2)
def _bank(seed: int) -> TextureBank:
    return TextureBank.generate(np.random.default_rng(np.random.SeedSequence([seed, 0x7E47])))
