"""Preemptive MSAC (fig. 6): weighted minimal samples and the truncated loss, batched.

The paper's "preemptive" MSAC draws each minimal sample with probability
``1 - p(x)``, p(x) being the previous frame's filtered probability of independent
motion, so samples avoid known movers. All hypotheses are drawn, estimated and
scored at once (arrays of shape (n, ...)) instead of one after the other: with
n = 32 hypotheses and a few hundred correspondences scoring everything costs
less than the loop's bookkeeping, so fig. 6's early exit (step 5) is not needed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import FloatArray

MIN_SAMPLE_WEIGHT = 1e-3   # a correspondence with p(x) = 1 can still be drawn, just rarely


def weighted_minimal_samples(rng: np.random.Generator, weights: NDArray[np.floating],
                             n: int, size: int) -> NDArray[np.int64]:
    """n minimal samples of ``size`` distinct indices each, index i drawn with prob. ~ weights[i].

    Efraimidis-Spirakis: the ``size`` largest keys ``log(u) / w`` of each row are a
    weighted sample without replacement. Returns (n, size) indices into ``weights``.
    Raises ValueError when there are fewer than ``size`` correspondences.
    """
    w = np.maximum(np.asarray(weights, dtype=np.float64), MIN_SAMPLE_WEIGHT)
    m = w.shape[0]
    if m < size:
        raise ValueError(f"{m} correspondences, a minimal sample needs {size}")
    keys = np.log(rng.random((n, m))) / w
    return np.argpartition(-keys, size - 1, axis=1)[:, :size]


def truncated_loss(delta: NDArray[np.floating], threshold: float) -> FloatArray:
    """MSAC loss ``L = sum_i rho(delta_i^2)`` with ``rho = min(delta^2, T^2)`` (fig. 6, step 4).

    delta: (n, M) errors (px) of M correspondences under n hypotheses; NaN counts as
    an outlier. Returns (n,).
    """
    d2 = np.asarray(delta, dtype=np.float64) ** 2
    d2 = np.where(np.isfinite(d2), d2, np.inf)
    loss: FloatArray = np.sum(np.minimum(d2, threshold * threshold), axis=-1)
    return loss
