"""Occlusion-edge evidence: two tests, both off by default (beyond the paper).

Where a near static surface ends in front of a farther one (a parked car's roof against a
facade, a building's corner against the next one), the Lucas-Kanade window holds both, and
at a T-junction the window's answer is the motion of neither: the junction slides along the
nearer edge, and the likelihood of eqs. 5-6 reads it as independent motion, frame after
frame, in the same place. Such a point is alone: a window's width to its left, right, above
and below, the flow is static again.

The test: measure flow at those four neighbours. A particle none of whose valid neighbours
looks independent (at least ``min_valid`` of them valid) is isolated, and its likelihood is
capped at its neighbours' highest. The hope is that road users are larger than that (a
pedestrian 6 px wide and 23 px tall has its upper and lower neighbours on its own body).
Measured, they are often not: with 9 px the simulator's cyclist (a thin 20 x 19 px outline)
and with 12 px pedestrians 23-26 px tall at ~50 m were found later, because the neighbours on
their thin parts look static; docs/detection.md has the figures. Off by default. The neighbours'
flow-length cue has no foot points (above the horizon only their direction test speaks).

The second test (``stability_offset_px``, :func:`flow_spread`) asks how much the particle's
flow changes when the window moves by a third of its width: each neighbour's LK starts at the
particle's answer on one pyramid level, and the largest change (less a floor) widens the
flow's std. A T-junction's answer moves with the window (0.6-1.0 px on the bend, 1.1 px on a
synthetic corner), a rigid patch's does not (median 0.1-0.4 px on the simulator's movers). It
halves the bend's false evidence, and it also weakens a pedestrian stepping out from behind a
parked car, which is itself an occlusion edge; docs/detection.md has the figures.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import FloatArray

# neighbour offsets in units of the spacing: left, right, above, below
NEIGHBOUR_OFFSETS: FloatArray = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]])


def neighbour_points(points: NDArray[np.floating], spacing_px: float) -> FloatArray:
    """(N, 4, 2) points ``spacing_px`` to the left, right, above and below each point (N, 2)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 1, 2)
    out: FloatArray = p + spacing_px * NEIGHBOUR_OFFSETS[None, :, :]
    return out


def isolated_likelihood(likelihood: NDArray[np.floating], nb_likelihood: NDArray[np.floating],
                        nb_valid: NDArray[np.bool_], static_below: float, min_valid: int
                        ) -> FloatArray:
    """Each likelihood (N,) capped at its neighbours' highest where it is isolated: at least
    ``min_valid`` of its neighbours (``nb_likelihood``, ``nb_valid``: (N, 4)) have a valid
    flow, and none of those has a likelihood of ``static_below`` or more."""
    lik = np.asarray(likelihood, dtype=np.float64)
    nl = np.asarray(nb_likelihood, dtype=np.float64).reshape(-1, 4)
    nv = np.asarray(nb_valid, dtype=bool).reshape(-1, 4)
    seen = np.where(nv, nl, -np.inf)
    top = seen.max(axis=1)
    isolated = (nv.sum(axis=1) >= min_valid) & (top < static_below)
    out: FloatArray = np.where(isolated, np.minimum(lik, np.maximum(top, 0.0)), lik)
    return out


def flow_spread(flow: NDArray[np.floating], nb_flow: NDArray[np.floating],
                nb_valid: NDArray[np.bool_]) -> FloatArray:
    """(N,) px: the largest difference between each flow (N, 2) and its neighbours' (N, 4, 2)
    with a valid flow (``nb_valid`` (N, 4); 0 without any). Measured with the window moved by
    a third of its width, a rigid patch gives nearly the same flow (median 0.1-0.4 px on the
    simulator's movers); a T-junction's answer depends on where the window sits (0.6-1.0 px
    on the bend's, whose flows are 2.6-3.5 px long)."""
    f = np.asarray(flow, dtype=np.float64).reshape(-1, 1, 2)
    nf = np.asarray(nb_flow, dtype=np.float64).reshape(-1, 4, 2)
    d = np.where(np.asarray(nb_valid, dtype=bool).reshape(-1, 4), np.hypot(*(nf - f).transpose(2, 0, 1)), 0.0)
    out: FloatArray = d.max(axis=1)
    return out
