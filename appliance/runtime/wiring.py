"""Configuration -> driver parameters. The drivers know nothing of ``appliance``; this is the seam.

Driver configuration errors (an unknown signal name, a malformed DBC) become
:class:`~appliance.errors.ConfigError` naming the file and the signal (exit 2).
"""

from __future__ import annotations

from appliance.config import Config
from appliance.errors import ConfigError
from drivers.vehicle_signals import VehicleCanConfigError, VehicleSignalDecoder


def vehicle_decoder(cfg: Config) -> VehicleSignalDecoder:
    """The pure speed / yaw-rate decoder configured by ``[vehicle_can]`` (or a recording's ``[can]``)."""
    v = cfg.vehicle_can
    try:
        return VehicleSignalDecoder(
            v.dbc, speed=v.speed, speed_unit=v.speed_unit, yaw_rate=v.yaw_rate,
            yaw_rate_unit=v.yaw_rate_unit, yaw_rate_sign=v.yaw_rate_sign,
        )
    except VehicleCanConfigError as exc:
        raise ConfigError(exc.dbc, exc.what or "vehicle_can.dbc", exc.problem) from None
