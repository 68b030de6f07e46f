"""Configuration -> driver parameters. The drivers know nothing of ``appliance``; this is the seam.

Driver configuration errors (an unknown signal name, a malformed DBC) become
:class:`~appliance.errors.ConfigError` naming the file and the signal (exit 2).
"""

from __future__ import annotations

from appliance.config import Config
from appliance.errors import ConfigError
from appliance.messages import TrackReport
from appliance.runtime.health import HealthStatus
from drivers.hmi_codec import HmiCodec, HmiDbcError, HmiStatus, HmiWarning
from drivers.vehicle_signals import VehicleCanConfigError, VehicleSignalDecoder


def vehicle_decoder(cfg: Config) -> VehicleSignalDecoder:
    """The pure speed / yaw-rate decoder of ``[vehicle_can]`` (or a recording's ``[can]``)."""
    v = cfg.vehicle_can
    try:
        return VehicleSignalDecoder(
            v.dbc,
            speed=v.speed,
            speed_unit=v.speed_unit,
            yaw_rate=v.yaw_rate,
            yaw_rate_unit=v.yaw_rate_unit,
            yaw_rate_sign=v.yaw_rate_sign,
        )
    except VehicleCanConfigError as exc:
        raise ConfigError(exc.dbc, exc.what or "vehicle_can.dbc", exc.problem) from None


def hmi_codec(cfg: Config, channel: str | None = None) -> HmiCodec:
    """Encoder of CollisionWarning / ApplianceStatus from ``[hmi_can]``."""
    h = cfg.hmi_can
    try:
        return HmiCodec(h.dbc, h.warning_id, h.status_id, channel=channel or h.channel)
    except HmiDbcError as exc:
        raise ConfigError(h.dbc, "hmi_can.dbc", str(exc)) from None


def hmi_warning(level: int, track: TrackReport | None) -> HmiWarning:
    """What CollisionWarning carries for the current warning level and the track behind it."""
    if level <= 0 or track is None:
        return HmiWarning(level=0)
    return HmiWarning(
        level=level,
        track_id=int(track.id) % 256,
        ttc_s=track.ttc_s,
        distance_m=track.distance_m,
        bearing_rad=track.bearing_rad,
    )


def hmi_status(status: HealthStatus) -> HmiStatus:
    f = status.faults
    return HmiStatus(
        state=status.state,
        fault_camera=f.camera,
        fault_vehicle_can_stale=f.vehicle_can_stale,
        fault_ptu=f.ptu,
        fault_overrun=f.overrun,
        frame_rate_hz=status.frame_rate,
        latency_ms=status.latency_ms,
    )
