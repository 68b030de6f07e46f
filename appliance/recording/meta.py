"""``meta.toml`` of a drive recording: camera intrinsics, mount and CAN decoding.

The ``[can]`` table of a recording overrides the appliance configuration's
``[vehicle_can]`` decoding keys, so recordings from different vehicles replay
correctly; ``[camera]`` and ``[mount]`` describe the recording itself.
Unknown extra tables (for example ``[simulator]``) are kept and ignored.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from appliance.config import Config, MountConfig, resource_path
from appliance.errors import RecordingError
from appliance.vision.geometry import PinholeCamera


@dataclass(frozen=True)
class CanDecoding:
    """How speed and yaw rate are decoded from the recording's ``can.log``."""

    dbc: str
    speed: str
    speed_unit: str
    yaw_rate: str
    yaw_rate_unit: str
    yaw_rate_sign: int


@dataclass(frozen=True)
class RecordingMeta:
    camera: PinholeCamera
    mount: MountConfig
    can: CanDecoding
    extra: dict[str, Any] = field(default_factory=dict)


_CAMERA_KEYS = ("width", "height", "fx", "fy", "cx", "cy")
_MOUNT_KEYS = ("x_m", "y_m", "z_m", "pitch_rad", "vehicle_width_m", "vehicle_front_m")


def meta_from_config(cfg: Config, extra: dict[str, Any] | None = None) -> RecordingMeta:
    """The meta of a recording made live with configuration ``cfg``."""
    c = cfg.camera
    v = cfg.vehicle_can
    return RecordingMeta(
        camera=PinholeCamera(c.width, c.height, c.fx, c.fy, c.cx, c.cy, tuple(c.distortion)),
        mount=cfg.mount,
        can=CanDecoding(v.dbc, v.speed, v.speed_unit, v.yaw_rate, v.yaw_rate_unit, v.yaw_rate_sign),
        extra=dict(extra or {}),
    )


def apply_meta(cfg: Config, meta: RecordingMeta) -> Config:
    """``cfg`` with the recording's camera, mount and CAN decoding in place."""
    cam = meta.camera
    return dataclasses.replace(
        cfg,
        camera=dataclasses.replace(
            cfg.camera,
            width=cam.width,
            height=cam.height,
            fx=cam.fx,
            fy=cam.fy,
            cx=cam.cx,
            cy=cam.cy,
            distortion=tuple(cam.distortion),
        ),
        mount=meta.mount,
        vehicle_can=dataclasses.replace(
            cfg.vehicle_can,
            dbc=meta.can.dbc,
            speed=meta.can.speed,
            speed_unit=meta.can.speed_unit,
            yaw_rate=meta.can.yaw_rate,
            yaw_rate_unit=meta.can.yaw_rate_unit,
            yaw_rate_sign=meta.can.yaw_rate_sign,
        ),
    )


def read_meta(path: Path, defaults: Config | None = None) -> RecordingMeta:
    """Parse and validate ``meta.toml``; every problem names the file and key.

    ``defaults`` supplies keys the spec marks optional (distortion, the ``[can]``
    table as a whole, ``mount.vehicle_rear_m``).
    """
    try:
        with path.open("rb") as fh:
            raw = tomllib.load(fh)
    except FileNotFoundError:
        raise RecordingError(path, "missing (every recording needs meta.toml)") from None
    except tomllib.TOMLDecodeError as exc:
        raise RecordingError(path, f"invalid TOML: {exc}") from None

    def table(name: str, required: bool = True) -> dict[str, Any]:
        t = raw.get(name)
        if t is None:
            if required:
                raise RecordingError(path, f"[{name}]: table missing")
            return {}
        if not isinstance(t, dict):
            raise RecordingError(path, f"{name}: must be a table")
        return t

    def number(
        t: dict[str, Any],
        sect: str,
        key: str,
        *,
        positive: bool = False,
        integer: bool = False,
        default: float | None = None,
    ) -> Any:
        if key not in t:
            if default is not None:
                return default
            raise RecordingError(path, f"{sect}.{key}: missing")
        v = t[key]
        ok = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok:
            kind = "an integer" if integer else "a number"
            raise RecordingError(path, f"{sect}.{key}: expected {kind}, got {v!r}")
        if not math.isfinite(v) or (positive and v <= 0):
            raise RecordingError(path, f"{sect}.{key}: {v!r} is out of range")
        return v if integer else float(v)

    cam = table("camera")
    dist = cam.get("distortion", [0.0, 0.0, 0.0, 0.0, 0.0])
    if (
        not isinstance(dist, list)
        or not all(isinstance(d, (int, float)) and not isinstance(d, bool) for d in dist)
        or len(dist) not in (4, 5, 8, 12, 14)
    ):
        raise RecordingError(path, "camera.distortion: expected 4, 5, 8, 12 or 14 numbers")
    camera = PinholeCamera(
        width=number(cam, "camera", "width", positive=True, integer=True),
        height=number(cam, "camera", "height", positive=True, integer=True),
        fx=number(cam, "camera", "fx", positive=True),
        fy=number(cam, "camera", "fy", positive=True),
        cx=number(cam, "camera", "cx"),
        cy=number(cam, "camera", "cy"),
        distortion=tuple(float(d) for d in dist),
    )

    mnt = table("mount")
    rear_default = defaults.mount.vehicle_rear_m if defaults is not None else 1.0
    mount = MountConfig(
        x_m=number(mnt, "mount", "x_m"),
        y_m=number(mnt, "mount", "y_m"),
        z_m=number(mnt, "mount", "z_m", positive=True),
        pitch_rad=number(mnt, "mount", "pitch_rad"),
        vehicle_width_m=number(mnt, "mount", "vehicle_width_m", positive=True),
        vehicle_front_m=number(mnt, "mount", "vehicle_front_m", positive=True),
        vehicle_rear_m=number(mnt, "mount", "vehicle_rear_m", default=rear_default),
    )

    can_t = table("can", required=defaults is None)
    base = defaults.vehicle_can if defaults is not None else None

    def text(key: str, choices: tuple[str, ...] = ()) -> str:
        if key not in can_t:
            if base is not None:
                return str(getattr(base, key))
            raise RecordingError(path, f"can.{key}: missing")
        v = can_t[key]
        if not isinstance(v, str) or (choices and v not in choices):
            want = f"one of {', '.join(choices)}" if choices else "a string"
            raise RecordingError(path, f"can.{key}: expected {want}, got {v!r}")
        return v

    dbc = text("dbc")
    if "dbc" in can_t:
        p = Path(dbc).expanduser()
        if not p.is_absolute():
            p = path.parent / p
            if not p.exists() and resource_path(dbc).exists():
                p = resource_path(dbc)  # the appliance's own vehicle.dbc, by name
        if not p.exists():
            raise RecordingError(path, f"can.dbc: file not found: {p}")
        dbc = str(p.resolve())
    sign = can_t.get("yaw_rate_sign", base.yaw_rate_sign if base is not None else 1)
    if sign not in (1, -1) or isinstance(sign, bool):
        raise RecordingError(path, f"can.yaw_rate_sign: expected 1 or -1, got {sign!r}")
    can = CanDecoding(
        dbc=dbc,
        speed=text("speed"),
        speed_unit=text("speed_unit", ("m/s", "km/h")),
        yaw_rate=text("yaw_rate"),
        yaw_rate_unit=text("yaw_rate_unit", ("rad/s", "deg/s")),
        yaw_rate_sign=int(sign),
    )
    extra = {k: v for k, v in raw.items() if k not in ("camera", "mount", "can")}
    return RecordingMeta(camera=camera, mount=mount, can=can, extra=extra)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def write_meta(path: Path, meta: RecordingMeta, dbc_name: str | None = None) -> None:
    """Write ``meta.toml``. ``dbc_name`` (relative to the recording) replaces the DBC path."""
    cam, mnt, can = meta.camera, meta.mount, meta.can
    lines = ["[camera]"]
    for k in _CAMERA_KEYS:
        lines.append(f"{k} = {_toml_value(getattr(cam, k))}")
    lines.append(f"distortion = {_toml_value([float(d) for d in cam.distortion])}")
    lines += ["", "[mount]"]
    for k in _MOUNT_KEYS + ("vehicle_rear_m",):
        lines.append(f"{k} = {_toml_value(float(getattr(mnt, k)))}")
    lines += ["", "[can]"]
    lines.append(f"dbc = {_toml_value(dbc_name or can.dbc)}")
    for k in ("speed", "speed_unit", "yaw_rate", "yaw_rate_unit", "yaw_rate_sign"):
        lines.append(f"{k} = {_toml_value(getattr(can, k))}")
    for name, tbl in meta.extra.items():
        if isinstance(tbl, dict):
            lines += ["", f"[{name}]"]
            lines += [f"{k} = {_toml_value(v)}" for k, v in tbl.items()]
    path.write_text("\n".join(lines) + "\n")
