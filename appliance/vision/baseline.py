"""Independent motion confirmed along a particle's lineage: the weakest of its last k links.

Eqs. 5-6 weigh one frame's flow, with one accuracy sigma_p for every flow. On weakly
textured road the per-frame LK error is of the order of the flow itself near the
horizon (on the simulator's bend: 0.2 px median, 0.9 px at the 90th percentile across
the epipolar line, for flows of 1-4 px), so about one static road point in ten looks
independent in any one frame, and resampling piles the particles onto whichever do.
The error of one frame is not repeated in the next (the patch has moved on: measured,
the share of static points with a cue > 0.5 in *every* one of k consecutive frames
falls from 11 % for k = 1 to 3 % for k = 2 and 1 % for k = 3), whereas an
independently moving object violates the static flow frame after frame.

So each particle carries the likelihoods of its last ``k - 1`` measurements (its
lineage: a resampled particle inherits its parent's, a particle drawn from the
importance function g starts without one), and its weight is the smallest likelihood
over the links it has, the current one included. A particle from g is weighed on its
one measurement, as in the paper.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import FloatArray


def lineage_weight(likelihood: NDArray[np.floating], history: FloatArray) -> FloatArray:
    """min(likelihood (N,), known entries of history (N, k-1)): NaN entries are unknown."""
    lk = np.asarray(likelihood, dtype=np.float64)
    if history.shape[1] == 0:
        return lk
    past = np.where(np.isnan(history), np.inf, history).min(axis=1)
    return np.asarray(np.minimum(lk, past), dtype=np.float64)


def advance_history(history: FloatArray, likelihood: NDArray[np.floating],
                    valid: NDArray[np.bool_]) -> FloatArray:
    """History (N, k-1) seen from the next frame: this frame's likelihood becomes the newest
    entry, the oldest is dropped. A particle whose flow is invalid loses its history (NaN)."""
    if history.shape[1] == 0:
        return history
    new = np.empty_like(history)
    new[:, 0] = likelihood
    new[:, 1:] = history[:, :-1]
    new[~np.asarray(valid, dtype=bool)] = np.nan
    return new


def inherit_history(history: FloatArray, parent: NDArray[np.int64]) -> FloatArray:
    """Histories (P, k-1) of the next particles: their parent's, NaN without one (``parent < 0``)."""
    out = np.full((len(parent), history.shape[1]), np.nan)
    has = parent >= 0
    if history.shape[1] and np.any(has):
        out[has] = history[parent[has]]
    return out
