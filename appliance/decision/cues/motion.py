"""Has the track moved over the ground? The appliance warns of independently moving objects.

A false detection on the static scene (road texture in a bend, a parked car) has a velocity
over ground near zero once its 3-D state has converged, while it can be anywhere before: a
track counts as moving once its 3-D state has ``min_frames`` contacts and moves at least
``min_speed_m_s`` and ``SIGMAS`` std (Mahalanobis, 2 dof) away from standing still. The
verdict is kept while the 3-D state is missing. A track that continues a hidden one which
was moving counts as moving until its new state has had the contacts to judge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from appliance.config import MotionCueConfig
from appliance.decision.cues.base import CueInput
from appliance.decision.ground_state import GroundTrack

SIGMAS = 3.0  # std from standing still a moving track's velocity over ground must be


@dataclass(frozen=True)
class MotionState:
    """moved: moving over ground; hold: a reacquired track counts as moving while its state has
    fewer contacts; t: when it last counted as moving (s)."""

    moved: bool = False
    hold: int = 0
    t: float = float("-inf")


def moves_over_ground(g: GroundTrack, cfg: MotionCueConfig) -> bool:
    """The object's velocity over ground is at least ``min_speed_m_s`` and ``SIGMAS`` std
    (Mahalanobis, 2 dof) away from standing still, after ``min_frames`` contacts."""
    v = g.velocity
    if g.updates < cfg.min_frames or g.speed < cfg.min_speed_m_s:
        return False
    Pv = g.P[2:4, 2:4]
    try:
        m2 = float(v @ np.linalg.solve(Pv, v))
    except np.linalg.LinAlgError:
        return False
    return m2 >= SIGMAS ** 2


class Motion:
    name: ClassVar[str] = "motion"
    estimates_ground: ClassVar[bool] = False

    def update(self, prev: MotionState | None, x: CueInput, cfg: MotionCueConfig) -> MotionState:
        prev = prev if prev is not None else MotionState()
        g = x.ground
        hold, t_moved = prev.hold, prev.t
        found = x.found.get(self.name) if x.found is not None else None
        if x.found is not None:
            hold = g.updates + cfg.min_frames if g is not None and found is not None \
                and found.moved else 0
            t_moved = found.t if found is not None else float("-inf")
        moved = (moves_over_ground(g, cfg) or g.updates < hold) if g is not None else prev.moved
        return MotionState(moved=moved, hold=hold, t=x.frame.t if moved else t_moved)
