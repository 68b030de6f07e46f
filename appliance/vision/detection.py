"""Section 2: the particle filter of fig. 3 with the modified resampling of fig. 4.

A particle is an image position where optical flow is measured. Per frame:

1. *predict*: each particle moves with its measured flow (its position in the new
   frame is the end of its correspondence) and diffusion is added after resampling;
2. *weigh*: the likelihood of independent motion at the measurement (``likelihood``);
3. *resample*: ``(1 - importance_fraction) N`` particles by systematic resampling of
   the weights; ``importance_fraction N`` fresh particles from the importance
   function g, whose weights at the next frame carry the correction of eq. 4.

Eq. 4 as printed, ``w = p(y|theta) / g(theta)``, is a density ratio and only makes
sense against the density the filter would otherwise sample from; we use the
uniform density u over the image (the filter's "object appears anywhere" prior):
``w = p(y|theta) u / g(theta)``. For ``importance = "uniform"`` the correction is 1;
for ``"road"`` (g biased to the band around and below the horizon where road users
appear) samples inside the band are weighted down and those outside up.

*Births* (beyond the paper, ``birth_fraction``): the static-scene pool of section 3
measures flow at ~300 corners every frame. Weighed with the same likelihood, those
correspondences are measurements of independent motion too, and a corner on a small
far mover is found far sooner than g's uniform samples find it (a 6 x 23 px pedestrian
gets one of 100 uniform samples every ~20 frames). Some of the importance samples are
therefore born next to the corners whose likelihood is high. They are draws from the
"object appears anywhere" prior already updated by those measurements, so their eq. 4
correction is 1: re-weighting them by ``u / g`` would undo exactly that update.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import DetectionConfig
from appliance.vision.geometry import FloatArray

ROAD_BAND_SHARE = 0.75       # share of g's mass in the road band ("road" importance)
ROAD_BAND_ABOVE = 0.125      # the band starts this fraction of the image height above the horizon


@dataclass(frozen=True)
class ImportanceDensity:
    """Importance function g over a width x height image.

    ``band_top`` None: uniform. Otherwise a mixture: ``band_share`` of the mass
    uniform over rows ``v >= band_top``, the rest uniform over the whole image.
    """

    width: int
    height: int
    band_top: float | None = None
    band_share: float = ROAD_BAND_SHARE

    def _band(self) -> tuple[float, float] | None:
        if self.band_top is None:
            return None
        top = float(np.clip(self.band_top, 0.0, self.height - 1.0))
        return top, (self.height - top) / self.height   # top row, band area / image area

    def sample(self, rng: np.random.Generator, n: int) -> FloatArray:
        """n positions (n, 2) px drawn from g."""
        u = rng.random((n, 2))
        pos = np.column_stack([u[:, 0] * (self.width - 1.0), u[:, 1] * (self.height - 1.0)])
        band = self._band()
        if band is not None:
            top = band[0]
            in_band = rng.random(n) < self.band_share
            pos[in_band, 1] = top + u[in_band, 1] * (self.height - 1.0 - top)
        return pos

    def correction(self, uv: NDArray[np.floating]) -> FloatArray:
        """Eq. 4's factor ``u / g`` at positions (n, 2): 1 everywhere for uniform g."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        band = self._band()
        if band is None:
            return np.ones(len(uv))
        top, area = band
        g_over_u = (1.0 - self.band_share) + np.where(uv[:, 1] >= top, self.band_share / area, 0.0)
        return 1.0 / g_over_u


def road_importance(width: int, height: int, horizon_row: float | None) -> ImportanceDensity:
    """g biased to the band from a little above the horizon to the bottom of the image."""
    if horizon_row is None or not np.isfinite(horizon_row) or horizon_row >= height - 1:
        return ImportanceDensity(width, height)
    return ImportanceDensity(width, height, band_top=horizon_row - ROAD_BAND_ABOVE * height)


BIRTHS_PER_POINT = 4   # births at most per seeding correspondence: one noisy corner seeds a few, not all


def birth_positions(points: NDArray[np.floating], likelihood: NDArray[np.floating], n: int,
                    threshold: float, spread_px: float, width: int, height: int,
                    rng: np.random.Generator) -> FloatArray:
    """Up to n birth positions (M, 2) px next to the correspondences ``points`` (S, 2)
    whose likelihood (S,) is at least ``threshold``: each picks one of them with
    probability proportional to its likelihood and adds a Gaussian offset of
    ``spread_px``. At most :data:`BIRTHS_PER_POINT` per such correspondence; none
    without any. Positions stay inside the image."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    lik = np.asarray(likelihood, dtype=np.float64).reshape(-1)
    hot = np.isfinite(lik) & (lik >= threshold) & np.all(np.isfinite(pts), axis=1)
    m = min(n, BIRTHS_PER_POINT * int(hot.sum()))
    if m <= 0:
        return np.empty((0, 2))
    seeds, w = pts[hot], lik[hot]
    idx = rng.choice(len(seeds), size=m, p=w / w.sum())
    out: FloatArray = seeds[idx] + rng.normal(0.0, spread_px, (m, 2))
    out[:, 0] = np.clip(out[:, 0], 0.0, width - 1.0)
    out[:, 1] = np.clip(out[:, 1], 0.0, height - 1.0)
    return out


def systematic_resample(weights: NDArray[np.floating], n: int, offset: float) -> NDArray[np.int64]:
    """n indices by systematic resampling of normalised ``weights`` with one offset in [0, 1).

    The algorithm of ``filterpy.monte_carlo.systematic_resample`` (positions
    ``(offset + k) / n`` on the cumulative weights), with the offset passed in:
    filterpy draws it from numpy's global random state, which would make replays
    depend on whatever else used it. ``tests/test_vision_detection.py`` checks the
    two agree.
    """
    w = np.asarray(weights, dtype=np.float64)
    cumulative = np.cumsum(w)
    cumulative[-1] = 1.0   # against rounding
    positions = (offset + np.arange(n)) / n
    return np.minimum(np.searchsorted(cumulative, positions, side="right"), len(w) - 1)


def resampling_weights(likelihood: NDArray[np.floating], valid: NDArray[np.bool_],
                       correction: NDArray[np.floating], floor: float) -> FloatArray:
    """Weights for resampling: likelihood (floored) times eq. 4's correction; 0 where invalid."""
    w = np.maximum(np.asarray(likelihood, dtype=np.float64), floor) * correction
    return np.where(np.asarray(valid, dtype=bool) & np.isfinite(w), w, 0.0)


def next_particles(x_cur: NDArray[np.floating], likelihood: NDArray[np.floating],
                   valid: NDArray[np.bool_], correction: NDArray[np.floating],
                   g: ImportanceDensity, cfg: DetectionConfig,
                   rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
    """Fig. 4: resample, diffuse, add importance samples (:func:`resample_particles`
    without the parents)."""
    out, corr, _, _ = resample_particles(x_cur, likelihood, valid, correction, g, cfg, rng)
    return out, corr


def resample_particles(x_cur: NDArray[np.floating], likelihood: NDArray[np.floating],
                       valid: NDArray[np.bool_], correction: NDArray[np.floating],
                       g: ImportanceDensity, cfg: DetectionConfig, rng: np.random.Generator,
                       births: NDArray[np.floating] | None = None
                       ) -> tuple[FloatArray, FloatArray, NDArray[np.int64], FloatArray]:
    """Fig. 4: resample, diffuse, add importance samples.

    x_cur: (N, 2) particle positions in the current frame (ends of the measured
    flow: the motion model of the prediction step); likelihood, valid, correction:
    (N,) each. Returns the positions (cfg.particles, 2) where flow is measured in
    the next frame, their eq. 4 corrections (1 for resampled particles), the index
    of each one's parent in x_cur (-1 for a sample of g) and its diffusion offset (px).
    With no valid particle (black frame, all tracks lost) every particle comes from g.
    ``births`` (M, 2) (:func:`birth_positions`) take the first M importance slots, with
    correction 1 and parent -1.
    """
    n = cfg.particles
    n_imp = round(cfg.importance_fraction * n)
    w = resampling_weights(likelihood, valid, correction, cfg.weight_floor)
    total = float(w.sum())
    if total <= 0.0:
        n_imp = n
    n_res = n - n_imp
    out = np.empty((n, 2))
    corr = np.ones(n)
    parent = np.full(n, -1, dtype=np.int64)
    offset = np.zeros((n, 2))
    if n_res > 0:
        idx = systematic_resample(w / total, n_res, float(rng.random()))
        offset[:n_res] = rng.normal(0.0, cfg.diffusion_px, (n_res, 2))
        out[:n_res] = np.asarray(x_cur, dtype=np.float64)[idx] + offset[:n_res]
        parent[:n_res] = idx
    # particles diffused out of the image are drawn from g instead (clipping them to the
    # border would pile them up in the corners, where the flow leaves the image)
    outside = np.zeros(n, dtype=bool)
    outside[:n_res] = ((out[:n_res, 0] < 0.0) | (out[:n_res, 0] > g.width - 1.0)
                       | (out[:n_res, 1] < 0.0) | (out[:n_res, 1] > g.height - 1.0))
    outside[n_res:] = True
    if births is not None and len(births) and n_imp > 0:   # correction 1, parent -1 as set above
        b = np.asarray(births, dtype=np.float64).reshape(-1, 2)[:n_imp]
        out[n_res:n_res + len(b)] = b
        outside[n_res:n_res + len(b)] = False
    fresh = g.sample(rng, int(outside.sum()))
    out[outside] = fresh
    corr[outside] = g.correction(fresh)
    parent[outside] = -1
    return out, corr, parent, offset
