"""Configuration -> driver parameters. The drivers know nothing of ``appliance``; this is the seam.

Driver configuration errors (an unknown signal name, a malformed DBC) become
:class:`~appliance.errors.ConfigError` naming the file and the signal (exit 2).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import can

from appliance.config import Config
from appliance.errors import ConfigError
from appliance.messages import TrackReport
from appliance.runtime.health import HealthStatus
from drivers.hmi_can import HmiCanWriter
from drivers.hmi_codec import HmiCodec, HmiDbcError, HmiStatus, HmiWarning
from drivers.ptu import PtuDriver, PtuSample
from drivers.vehicle_can import VehicleCanReader
from drivers.vehicle_signals import (
    VehicleCanConfigError,
    VehicleSignal,
    VehicleSignalDecoder,
)


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


def check_config(cfg: Config) -> None:
    """What the drivers refuse at start, checked before anything runs: the vehicle DBC and
    its signal names, the HMI DBC (:class:`ConfigError`, exit 2)."""
    vehicle_decoder(cfg)
    hmi_codec(cfg)


def vehicle_reader(
    cfg: Config,
    sink: Callable[[VehicleSignal], None],
    raw_sink: Callable[[can.Message], None] | None = None,
    *,
    bus: tuple[str, str] | None = None,
    stale_scale: float = 1.0,
) -> VehicleCanReader:
    """The vehicle CAN reader of ``[vehicle_can]`` (``bus``: (interface, channel) instead of
    the configured one; ``stale_scale`` stretches the staleness limit of a slowed playback)."""
    v = cfg.vehicle_can
    interface, channel = bus or (v.interface, v.channel)
    return VehicleCanReader(
        vehicle_decoder(cfg),
        interface=interface,
        channel=channel,
        stale_s=v.stale_s * stale_scale,
        sink=sink,
        raw_sink=raw_sink,
    )


def ptu_driver(cfg: Config, port: str, sink: Callable[[PtuSample], None]) -> PtuDriver:
    """The pan-tilt unit driver of ``[ptu]`` on ``port`` (the configured one, or a simulator's)."""
    p = cfg.ptu
    return PtuDriver(
        port,
        baud=p.baud,
        pan_sign=p.pan_sign,
        tilt_sign=p.tilt_sign,
        pan_offset_rad=p.pan_offset_rad,
        tilt_offset_rad=p.tilt_offset_rad,
        poll_hz=p.poll_hz,
        timeout_s=p.timeout_s,
        speed_rad_s=p.speed_rad_s,
        sink=sink,
    )


def hmi_writer(cfg: Config, log_path: Path, *, bus: tuple[str, str] | None = None) -> HmiCanWriter:
    """The HMI CAN writer of ``[hmi_can]``, logging every frame sent to ``log_path``."""
    h = cfg.hmi_can
    interface, channel = bus or (h.interface, h.channel)
    return HmiCanWriter(
        hmi_codec(cfg, channel),
        interface=interface,
        channel=channel,
        period_s=h.period_s,
        log_path=log_path,
    )


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
