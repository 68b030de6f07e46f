"""The track's 3-D state on the road, from its ground contact (``ground_state.py``).

Every frame the state is predicted with the ego motion from CAN removed (coasting at
constant velocity while the track has no contact); a ground contact then updates it, or
starts it, with its velocity across the line of sight from the bearing rate
(:func:`ground_state.velocity_prior`). A new track whose first contact continues a hidden
one (``x.found``) takes that one's coasted state. Without a contact for ``coast_s`` the
state is dropped. For ``LOWERED_MEMORY_S`` after the foot cue last found the object reaching
below its cluster, a contact reading farther than predicted counts less
(:func:`ground_state.one_sided`): its cluster is known to stop above its feet; far away,
where its legs are thinner than the flow's window, much less (:func:`far_factor`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from appliance.config import GroundCueConfig
from appliance.decision.cues.base import CueInput
from appliance.decision.cues.bearing import bearing_fit
from appliance.decision.frame import lowered_contact
from appliance.decision.ground_state import (
    GroundModel,
    GroundTrack,
    ground_absorb,
    ground_predict,
    ground_update,
    velocity_prior,
)

LOWERED_MEMORY_S = 1.0   # s, after the foot cue last lowered a contact: its contacts one-sided
RATE_STD_FLOOR = 0.01    # rad/s, the bearing rate is known to this at best (velocity_prior)
LEG_WIDTH_M = 0.15       # m, a leg's width: narrower in the image than the flow's window, its
                         #   flow is the road's behind it
THIN_FAR_FACTOR = 10.0   # a contact reading farther than predicted, where legs are that thin


def far_factor(range_m: float, fx: float, window_px: float, near: float) -> float:
    """How much less a contact reading farther than predicted counts on an object known to
    reach below its cluster (:func:`ground_state.one_sided`), at ``range_m`` for a camera of
    focal length ``fx`` px and a flow window of ``window_px``. Where a leg (``LEG_WIDTH_M``)
    is narrower than the window, its flow is the road's behind it, and a walker's planted foot
    moves like the road anyway: only a swinging foot shows where the object ends, one step in
    two, and the contacts between steps sit on the knees; they are all but ignored
    (``THIN_FAR_FACTOR``). Nearer, the legs fill the window and the feet are seen every frame:
    ``near``."""
    leg_px = LEG_WIDTH_M * fx / max(range_m, 1e-3)
    return THIN_FAR_FACTOR if leg_px < window_px else near


@dataclass(frozen=True)
class GroundState:
    """The 3-D state (None: none yet, or dropped) and whether a contact updated it this frame."""

    ground: GroundTrack | None
    fresh: bool
    lowered_t: float | None = None


def ground_model(cfg: GroundCueConfig) -> GroundModel:
    """The 3-D filter's parameters with the table's contact std and range."""
    return GroundModel(contact_std_px=cfg.contact_std_px, max_range_m=cfg.max_range_m)


class GroundContact:
    name: ClassVar[str] = "ground"
    estimates_ground: ClassVar[bool] = True

    def update(self, prev: GroundState | None, x: CueInput, cfg: GroundCueConfig) -> GroundState:
        f = x.frame
        model = ground_model(cfg)
        g = x.ground
        if g is not None:
            # no contact in the frame before: coasting, at constant velocity
            g = ground_predict(g, f.dt, f.sensors, model, steady=f.t - g.t_update > 1.5 * f.dt)
        contact = x.meas.contact
        lowered_t = prev.lowered_t if prev is not None else None
        low = x.now.get("foot")
        if low is not None and low.rows > 0 and x.track.cluster is not None \
                and x.track.confirmed and not any(x.meas.sides):
            # the object reaches below its cluster: its feet are lower (``object_foot.py``)
            contact = None if low.at_edge else lowered_contact(
                x.track.cluster, f, model, contact, low.bottom)
            lowered_t = f.t
        if contact is not None:
            if x.found is not None and x.found.ground is not None:
                # the occluded object is back: its coasted state takes the contact
                g = ground_update(x.found.ground, contact, f.t)
            else:
                bearings = x.now.get("bearing")
                fit = bearing_fit(bearings.history) if bearings is not None else None
                prior = None if fit is None else velocity_prior(
                    contact.z, fit[0], f.speed, f.yaw_rate, (f.mount.x_m, f.mount.y_m), model,
                    max(fit[1], RATE_STD_FLOOR))
                above = lowered_t is not None and f.t - lowered_t <= LOWERED_MEMORY_S
                factor = far_factor(contact.range_from(f.pose), f.camera.fx, f.window_px,
                                    model.far_factor)
                g = ground_absorb(g, contact, f.t, model, prior, above_feet=above,
                                  far_factor=factor)
        fresh = g is not None and g.t_update == f.t
        if g is not None and not fresh and f.t - g.t_update > cfg.coast_s:
            g = None
        return GroundState(ground=g, fresh=fresh, lowered_t=lowered_t)
