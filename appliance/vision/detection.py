"""Section 2: the particle filter of fig. 3 with the modified resampling of fig. 4.

A particle is an image position where optical flow is measured. Per frame:

1. *predict*: each particle moves with its measured flow (its position in the new
   frame is the end of its correspondence) and diffusion is added after resampling;
2. *weigh*: the likelihood of independent motion at the measurement (``likelihood``);
3. *resample*: ``(1 - importance_fraction) N`` particles by systematic resampling of
   the weights; ``importance_fraction N`` fresh particles from the importance
   function g.

g is uniform over the image: an object can appear anywhere. Eq. 4 as printed,
``w = p(y|theta) / g(theta)``, is a density ratio against the density the filter would
otherwise sample from, the same uniform "object appears anywhere" prior, so its
correction ``u / g`` is 1 and an importance sample is weighed like any other particle.

*Births* (beyond the paper, :data:`BIRTH_FRACTION`): the static-scene pool of section 3
measures flow at ``refinement.static_points`` corners every frame. Weighed with the same likelihood, those
correspondences are measurements of independent motion too, and a corner on a small
far mover is found far sooner than g's uniform samples find it (a 6 x 23 px pedestrian
gets one of 100 uniform samples every ~20 frames). Some of the importance samples are
therefore born next to the corners whose likelihood is high. They are draws from the
"object appears anywhere" prior already updated by those measurements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import DetectionConfig
from appliance.vision.geometry import FloatArray

WEIGHT_FLOOR = 0.02      # a particle is resampled with a weight of at least this: fewer clumps
                         #   on false evidence, at the cost of slower gathering on objects
BIRTH_FRACTION = 0.1     # share of the N particles born next to static-pool correspondences
BIRTH_LIKELIHOOD = 0.5   # a correspondence with at least this likelihood seeds births
BIRTH_SPREAD_PX = 3.0    # px, std of a birth around its correspondence's end point


@dataclass(frozen=True)
class ImportanceDensity:
    """Importance function g: uniform over a width x height image."""

    width: int
    height: int

    def sample(self, rng: np.random.Generator, n: int) -> FloatArray:
        """n positions (n, 2) px drawn from g."""
        u = rng.random((n, 2))
        return np.column_stack([u[:, 0] * (self.width - 1.0), u[:, 1] * (self.height - 1.0)])


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
                       floor: float) -> FloatArray:
    """Weights for resampling: the likelihood, at least ``floor``; 0 where the flow is invalid."""
    w = np.maximum(np.asarray(likelihood, dtype=np.float64), floor)
    return np.where(np.asarray(valid, dtype=bool) & np.isfinite(w), w, 0.0)


def resample_particles(x_cur: NDArray[np.floating], likelihood: NDArray[np.floating],
                       valid: NDArray[np.bool_], g: ImportanceDensity, cfg: DetectionConfig,
                       rng: np.random.Generator, births: NDArray[np.floating] | None = None,
                       weight_floor: float = WEIGHT_FLOOR) -> FloatArray:
    """Fig. 4: resample, diffuse, add importance samples.

    x_cur: (N, 2) particle positions in the current frame (ends of the measured
    flow: the motion model of the prediction step); likelihood, valid: (N,) each.
    Returns the positions (cfg.particles, 2) where flow is measured in the next frame.
    With no valid particle (black frame, all tracks lost) every particle comes from g.
    ``births`` (M, 2) (:func:`birth_positions`) take the first M importance slots.
    """
    n = cfg.particles
    n_imp = round(cfg.importance_fraction * n)
    w = resampling_weights(likelihood, valid, weight_floor)
    total = float(w.sum())
    if total <= 0.0:
        n_imp = n
    n_res = n - n_imp
    out = np.empty((n, 2))
    if n_res > 0:
        idx = systematic_resample(w / total, n_res, float(rng.random()))
        diffusion = rng.normal(0.0, cfg.diffusion_px, (n_res, 2))
        out[:n_res] = np.asarray(x_cur, dtype=np.float64)[idx] + diffusion
    # particles diffused out of the image are drawn from g instead (clipping them to the
    # border would pile them up in the corners, where the flow leaves the image)
    outside = np.zeros(n, dtype=bool)
    outside[:n_res] = ((out[:n_res, 0] < 0.0) | (out[:n_res, 0] > g.width - 1.0)
                       | (out[:n_res, 1] < 0.0) | (out[:n_res, 1] > g.height - 1.0))
    outside[n_res:] = True
    if births is not None and len(births) and n_imp > 0:
        b = np.asarray(births, dtype=np.float64).reshape(-1, 2)[:n_imp]
        out[n_res:n_res + len(b)] = b
        outside[n_res:n_res + len(b)] = False
    out[outside] = g.sample(rng, int(outside.sum()))
    return out
