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
    def generate(rng: np.random.Generator) -> TextureBank:
        bank = TextureBank()
        bank.add(tx.asphalt(rng))
        bank.add(tx.paving(rng))
        bank.add(tx.kerb(rng))
        bank.add(ot.roof(rng))
        for k in range(N_FACADES):
            bank.add(ot.facade(rng, k))
        for k in range(N_CAR_SKINS):
            body = float(rng.uniform(40, 220))
            bank.add(tx.make_texture(f"car_side{k}", ot.car_side(rng, body), False))
            bank.add(tx.make_texture(f"car_front{k}", ot.car_end(rng, body, True), False))
            bank.add(tx.make_texture(f"car_rear{k}", ot.car_end(rng, body, False), False))
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
        return bank

    @staticmethod
    def for_seed(seed: int) -> TextureBank:
        """The bank of a seed (same seed, same textures in every scenario); cached, read-only."""
        return _bank_for_seed(seed)

    # ------------------------------------------------------------ skins

    def car_skin(self, k: int) -> BoxSkin:
        k %= N_CAR_SKINS
        side = self[f"car_side{k}"]
        return BoxSkin(self[f"car_front{k}"], self[f"car_rear{k}"], side, side, self["roof"])

    def person_skin(self, k: int) -> BoxSkin:
        k %= N_PEOPLE
        front, side = self[f"ped_front{k}"], self[f"ped_side{k}"]
        return BoxSkin(front, front, side, side, side)

    def cyclist_skin(self, k: int) -> BoxSkin:
        k %= 2
        front, side = self[f"cyc_front{k}"], self[f"cyc_side{k}"]
        return BoxSkin(front, front, side, side, front)

    def skin(self, kind: str, k: int) -> BoxSkin:
        if kind == "car":
            return self.car_skin(k)
        if kind == "pedestrian":
            return self.person_skin(k)
        if kind == "cyclist":
            return self.cyclist_skin(k)
        raise ValueError(f"unknown mover class {kind!r}")


@lru_cache(maxsize=2)
def _bank_for_seed(seed: int) -> TextureBank:
    return TextureBank.generate(np.random.default_rng(np.random.SeedSequence([seed, 0x7E47])))
