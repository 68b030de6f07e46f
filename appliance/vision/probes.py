"""The flow at pixels the decision stage asks about.

Decision never sees images. Where it needs the flow at given pixels of the current frame
(how far up a tracked object reaches; whether something nearer covers a hidden one; whether
a hidden object's head keeps its bearing), it names the pixels, and :func:`measure_points`
measures them here: pyramidal Lucas-Kanade from the current frame back to the previous one,
forward-backward checked (:func:`flow.flow_into`), each point starting where the refined
camera rotation alone moved it (so a PTU pan of 15 px per frame stays within the pyramid's
reach). All requests of a frame share one pair of LK calls.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from appliance.config import FlowConfig
from appliance.vision.flow import flow_into
from appliance.vision.geometry import FloatArray, PinholeCamera, euler_to_matrix, lk_start

K = TypeVar("K", bound=Hashable)


@dataclass(frozen=True)
class PointFlow:
    """The measured flow (M, 2) px (current position minus previous) at each requested point,
    the rotation's flow included, and where it is valid (M,)."""

    flow: FloatArray
    valid: NDArray[np.bool_]


def measure_points(prev: NDArray[np.uint8], cur: NDArray[np.uint8],
                   requests: Mapping[K, FloatArray], rotation: NDArray[np.floating],
                   camera: PinholeCamera, cfg: FlowConfig) -> dict[K, PointFlow]:
    """The flow at each request's points (M, 2) px of ``cur``; ``rotation``: the refined
    camera rotation since ``prev`` (Euler angles, rad, ``X_cur = R X_prev + t``)."""
    keys = list(requests)
    pts = [np.asarray(requests[k], dtype=np.float64).reshape(-1, 2) for k in keys]
    out: dict[K, PointFlow] = {}
    sizes = [len(p) for p in pts]
    if sum(sizes) == 0:
        return {k: PointFlow(np.zeros((0, 2)), np.zeros(0, dtype=bool)) for k in keys}
    allpts = np.concatenate(pts)
    R = euler_to_matrix(np.asarray(rotation, dtype=np.float64))
    flow, valid = flow_into(prev, cur, allpts, cfg, lk_start(camera, allpts, R.T))
    start = 0
    for k, n in zip(keys, sizes):
        out[k] = PointFlow(flow[start:start + n], valid[start:start + n])
        start += n
    return out
