"""How one simulated drive looks: its camera, mount, materials, body bounce and sensor.

Every recording draws a :class:`Look` from its own seed (with the scenario), so a
set of seeds is a set of cameras, mounts, worlds and sensors, not one world seen
over and over. The ranges are all here, in :data:`RANGES`; docs/simulator.md
lists them. A look changes how the world is seen, never what happens in it: the
scenario's courses, collision time and truth are the same for every look, and the
truth is projected with the look's camera.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from appliance.sim.effects import Effects


@dataclass(frozen=True)
class LookRanges:
    """The range each look parameter is drawn from (uniform unless the draw says log-uniform).

    fx_px: focal length (log-uniform, so fields of view 32-71 deg spread evenly);
    fy_ratio: fy / fx; principal_offset: principal point from the image centre, share of the
    width and height; mount_height_m, mount_pitch_rad (positive looks down);
    texture_contrast: every texture's deviations from its mean are scaled by this
    (log-uniform); plain_movers: probability that the movers wear plain clothing / plain
    paint; bounce_scale: body pitch and roll amplitudes on bumps times this (log-uniform,
    pitch and roll apart); colour: probability of a colour (BGR) recording;
    saturation: largest chroma of an object's colour (relative gain); white_balance: largest
    chroma of the whole frame's cast; exposure: mean gain (log-uniform); drift: amplitude of
    the slow exposure drift (relative) and drift_period_s its period; flicker: probability and
    amplitude of a fast exposure flicker; vignetting: relative fall-off in the image corners;
    blur_sigma_px: optical blur; motion_blur: probability and shutter fraction of the frame
    interval (0 = no motion blur); noise_sigma: sensor noise std (DN, per channel).
    """

    fx_px: tuple[float, float] = (450.0, 1100.0)
    fy_ratio: tuple[float, float] = (0.99, 1.01)
    principal_offset: tuple[float, float] = (-0.025, 0.025)
    mount_height_m: tuple[float, float] = (1.1, 1.6)
    mount_pitch_rad: tuple[float, float] = (0.0, 0.08)
    texture_contrast: tuple[float, float] = (0.5, 1.3)
    plain_movers: float = 0.3
    bounce_scale: tuple[float, float] = (0.5, 2.0)
    colour: float = 0.5
    saturation: tuple[float, float] = (0.1, 0.6)
    white_balance: tuple[float, float] = (0.0, 0.08)
    exposure: tuple[float, float] = (0.8, 1.2)
    drift: tuple[float, float] = (0.0, 0.12)
    drift_period_s: tuple[float, float] = (5.0, 20.0)
    flicker: tuple[float, float, float] = (0.5, 0.01, 0.04)
    vignetting: tuple[float, float] = (0.0, 0.35)
    blur_sigma_px: tuple[float, float] = (0.0, 0.9)
    motion_blur: tuple[float, float, float] = (0.35, 0.2, 0.5)
    noise_sigma: tuple[float, float] = (0.5, 3.0)


RANGES = LookRanges()


@dataclass(frozen=True)
class Look:
    """One drive's camera intrinsics (VGA stays VGA), mount height and pitch, materials, body
    bounce and sensor (see :class:`LookRanges` for the meaning and range of each)."""

    fx: float
    fy: float
    cx: float
    cy: float
    mount_height_m: float
    mount_pitch_rad: float
    texture_contrast: float
    plain_movers: bool
    bounce_pitch_scale: float
    bounce_roll_scale: float
    effects: Effects

    @staticmethod
    def draw(rng: np.random.Generator, width: int, height: int, r: LookRanges = RANGES) -> Look:
        """A look for a ``width`` x ``height`` camera, every parameter from ``rng``."""

        def uniform(lo_hi: tuple[float, float]) -> float:
            return float(rng.uniform(*lo_hi))

        def log_uniform(lo_hi: tuple[float, float]) -> float:
            return float(np.exp(rng.uniform(np.log(lo_hi[0]), np.log(lo_hi[1]))))

        def chance(p: float) -> bool:
            return bool(rng.random() < p)

        fx = log_uniform(r.fx_px)
        fy = fx * uniform(r.fy_ratio)
        cx = (width - 1) / 2.0 + width * uniform(r.principal_offset)
        cy = (height - 1) / 2.0 + height * uniform(r.principal_offset)
        geometry = (uniform(r.mount_height_m), uniform(r.mount_pitch_rad))
        materials = (log_uniform(r.texture_contrast), chance(r.plain_movers))
        bounce = (log_uniform(r.bounce_scale), log_uniform(r.bounce_scale))
        colour = chance(r.colour)
        flicker_on, motion_on = chance(r.flicker[0]), chance(r.motion_blur[0])
        effects = Effects(
            colour=colour,
            saturation=uniform(r.saturation) if colour else 0.0,
            white_balance=uniform(r.white_balance) if colour else 0.0,
            exposure=log_uniform(r.exposure),
            drift=uniform(r.drift),
            drift_period_s=uniform(r.drift_period_s),
            flicker=float(rng.uniform(*r.flicker[1:])) if flicker_on else 0.0,
            vignetting=uniform(r.vignetting),
            blur_sigma=uniform(r.blur_sigma_px),
            blur_exposure=float(rng.uniform(*r.motion_blur[1:])) if motion_on else 0.0,
            noise_sigma=uniform(r.noise_sigma),
        )
        return Look(fx, fy, cx, cy, *geometry, *materials, *bounce, effects)

    def table(self) -> dict[str, float | bool]:
        """What the recording's camera and mount tables do not say (materials, bounce, sensor),
        for ``meta.toml [simulator]``; numbers to 4 decimals."""
        values: dict[str, float | bool] = {
            "texture_contrast": self.texture_contrast,
            "plain_movers": self.plain_movers,
            "bounce_pitch_scale": self.bounce_pitch_scale,
            "bounce_roll_scale": self.bounce_roll_scale,
        }
        values.update(dataclasses.asdict(self.effects))
        return {k: v if isinstance(v, bool) else round(float(v), 4) for k, v in values.items()}

