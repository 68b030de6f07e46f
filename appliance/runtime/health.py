"""Appliance health: the ``ApplianceStatus`` state and fault bits, and their changes.

State (spec): 0 starting, 1 ok, 2 degraded, 3 fault. Camera lost -> fault (and the
warnings are cleared); vehicle CAN stale, PTU lost or processing overrun -> degraded.
Each change is reported once by :meth:`Health.update`, not every frame, with what the
appliance can still warn of (:func:`capability`).
"""

from __future__ import annotations

from dataclasses import dataclass

STARTING, OK, DEGRADED, FAULT = 0, 1, 2, 3
STATE_NAMES = {STARTING: "starting", OK: "ok", DEGRADED: "degraded", FAULT: "fault"}


@dataclass(frozen=True)
class Faults:
    camera: bool = False
    vehicle_can_stale: bool = False
    ptu: bool = False
    overrun: bool = False

    def names(self) -> list[str]:
        return [n for n in ("camera", "vehicle_can_stale", "ptu", "overrun") if getattr(self, n)]


@dataclass(frozen=True)
class HealthStatus:
    """What ApplianceStatus carries: state, fault bits, processed frame rate (1/s), latency (ms)."""

    state: int
    faults: Faults
    frame_rate: float
    latency_ms: float

    @property
    def state_name(self) -> str:
        return STATE_NAMES[self.state]

    def describe(self) -> str:
        faults = ", ".join(self.faults.names()) or "none"
        return (
            f"{self.state_name}; faults: {faults}; {self.frame_rate:.1f} frames/s; "
            f"latency {self.latency_ms:.1f} ms"
        )


def capability(faults: Faults) -> str:
    """What the appliance can still warn of with these faults (the decision stage's rules)."""
    if faults.camera:
        return "no warnings: no frames"
    if faults.vehicle_can_stale or faults.ptu:
        return "cautions only, from the image's growth and bearing: ego motion unknown"
    return "full"


def state_of(started: bool, faults: Faults) -> int:
    if faults.camera:
        return FAULT
    if not started:
        return STARTING
    if faults.vehicle_can_stale or faults.ptu or faults.overrun:
        return DEGRADED
    return OK


class Health:
    """Tracks the status and reports each change of state or fault bits exactly once."""

    def __init__(self) -> None:
        self.status = HealthStatus(STARTING, Faults(), 0.0, 0.0)
        self.changes = 0

    def update(
        self, started: bool, faults: Faults, frame_rate: float, latency_ms: float
    ) -> str | None:
        """New status; returns a one-line description when state or faults changed, else None."""
        new = HealthStatus(state_of(started, faults), faults, frame_rate, latency_ms)
        changed = (new.state, new.faults) != (self.status.state, self.status.faults)
        self.status = new
        if changed:
            self.changes += 1
            line = f"status {new.state_name} (faults: {', '.join(faults.names()) or 'none'})"
            can = capability(faults)
            return line if can == "full" else f"{line}; warnings: {can}"
        return None
