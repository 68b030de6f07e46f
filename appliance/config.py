"""Configuration: TOML files -> typed, frozen dataclasses.

``config/default.toml`` (shipped as ``appliance.resources``) is the single source
of defaults and documents every key. A user file overrides only the keys it
names. Every problem raises :class:`~appliance.errors.ConfigError` naming the
file, the key and what is wrong (the command line turns it into exit status 2).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Union

from appliance.errors import ConfigError

RESOURCES = "appliance.resources"


def _p(
    lo: float | None = None,
    hi: float | None = None,
    *,
    choices: tuple[Any, ...] = (),
    path: bool = False,
    lo_open: bool = False,
) -> Any:
    """Field with its valid range: ``lo <= v <= hi`` (``lo < v`` with ``lo_open``)."""
    return field(
        metadata={"lo": lo, "hi": hi, "choices": choices, "path": path, "lo_open": lo_open}
    )


@dataclass(frozen=True)
class CameraConfig:
    device: str = _p()
    width: int = _p(16, 8192)
    height: int = _p(16, 8192)
    fps: float = _p(0.0, 240.0, lo_open=True)
    pixel_format: str = _p(choices=("GREY", "YUYV", "MJPG"))
    fx: float = _p(0.0, lo_open=True)
    fy: float = _p(0.0, lo_open=True)
    cx: float = _p()
    cy: float = _p()
    distortion: tuple[float, ...] = _p()
    stale_s: float = _p(0.0, lo_open=True)
    timestamps: str = _p(choices=("auto", "retrieval"))


@dataclass(frozen=True)
class MountConfig:
    x_m: float = _p(-10.0, 20.0)
    y_m: float = _p(-5.0, 5.0)
    z_m: float = _p(0.0, 5.0, lo_open=True)
    pitch_rad: float = _p(-1.0, 1.0)
    vehicle_width_m: float = _p(0.0, 5.0, lo_open=True)
    vehicle_front_m: float = _p(0.0, 20.0, lo_open=True)
    vehicle_rear_m: float = _p(0.0, 10.0)


@dataclass(frozen=True)
class VehicleCanConfig:
    interface: str = _p()
    channel: str = _p()
    dbc: str = _p(path=True)
    speed: str = _p()
    speed_unit: str = _p(choices=("m/s", "km/h"))
    yaw_rate: str = _p()
    yaw_rate_unit: str = _p(choices=("rad/s", "deg/s"))
    yaw_rate_sign: int = _p(choices=(1, -1))
    stale_s: float = _p(0.0, lo_open=True)


@dataclass(frozen=True)
class HmiCanConfig:
    interface: str = _p()
    channel: str = _p()
    dbc: str = _p(path=True)
    warning_id: int = _p(0, 0x7FF)
    status_id: int = _p(0, 0x7FF)
    period_s: float = _p(0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class PtuConfig:
    enabled: bool = _p()
    port: str = _p()
    baud: int = _p(choices=(600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200))
    pan_sign: int = _p(choices=(1, -1))
    tilt_sign: int = _p(choices=(1, -1))
    pan_offset_rad: float = _p(-3.2, 3.2)
    tilt_offset_rad: float = _p(-1.6, 1.6)
    poll_hz: float = _p(0.0, 200.0, lo_open=True)
    timeout_s: float = _p(0.0, 10.0, lo_open=True)
    speed_rad_s: float = _p(0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class FlowConfig:
    pyramid_levels: int = _p(0, 6)
    window_px: int = _p(3, 63)
    fb_threshold_px: float = _p(0.0, lo_open=True)


@dataclass(frozen=True)
class DetectionConfig:
    particles: int = _p(1, 100000)
    importance_fraction: float = _p(0.0, 1.0)
    diffusion_px: float = _p(0.0, 100.0)
    sigma_e_px: float = _p(0.0, lo_open=True)
    sigma_p_px: float = _p(0.0, lo_open=True)
    likelihood: str = _p(choices=("direction", "magnitude", "combined"))
    magnitude_sigma: float = _p(0.0, lo_open=True)
    max_flow_px: float = _p(0.0, lo_open=True)
    standstill_speed_m_s: float = _p(0.0)
    standstill_residual_px: float = _p(0.0, lo_open=True)


@dataclass(frozen=True)
class RefinementConfig:
    static_points: int = _p(5, 100000)
    sigma_epipole_rad: float = _p(0.0, lo_open=True)
    sigma_rot_x_rad: float = _p(0.0, lo_open=True)
    sigma_rot_y_rad: float = _p(0.0, lo_open=True)
    sigma_rot_z_rad: float = _p(0.0, lo_open=True)
    sigma_l_px: float = _p(0.0, lo_open=True)
    msac_threshold_px: float = _p(0.0, lo_open=True)
    msac_hypotheses: int = _p(1, 10000)


@dataclass(frozen=True)
class ProbabilityMapConfig:
    gauss_window_px: int = _p(1, 255)
    temporal_alpha: float = _p(0.0, 1.0, lo_open=True)
    scale: int = _p(1, 16)


@dataclass(frozen=True)
class ClusteringConfig:
    threshold: float = _p(0.0, 1.0, lo_open=True)
    dilation_px: int = _p(0, 255)
    min_correspondences: int = _p(1, 100000)


@dataclass(frozen=True)
class TrackingConfig:
    position_std_px: float = _p(0.0, lo_open=True)
    velocity_std_px: float = _p(0.0, lo_open=True)
    process_std_px: float = _p(0.0, lo_open=True)
    initial_position_std_px: float = _p(0.0, lo_open=True)
    initial_velocity_std_px: float = _p(0.0, lo_open=True)
    gate_px: float = _p(0.0, lo_open=True)
    gate_sigmas: float = _p(0.0, lo_open=True)
    confirm_frames: int = _p(1, 1000)
    max_missed: int = _p(1, 1000)
    merge_px: float = _p(0.0)


# ------------------------------------------------------------ per-track cues
# One table per cue of ``appliance/decision/cues`` (``[cue.<name>]``); a cue without
# parameters a user would change has none.


@dataclass(frozen=True)
class GroundCueConfig:
    contact_std_px: float = _p(0.0, 100.0, lo_open=True)
    max_range_m: float = _p(1.0, 1000.0)
    coast_s: float = _p(0.0, 10.0)


@dataclass(frozen=True)
class CrossingCueConfig:
    window_s: float = _p(0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class ScaleCueConfig:
    min_frames: int = _p(2, 1000)


@dataclass(frozen=True)
class RangeRateCueConfig:
    std_gain: float = _p(0.0, 100.0, lo_open=True)


@dataclass(frozen=True)
class MotionCueConfig:
    min_speed_m_s: float = _p(0.0, 50.0)
    min_frames: int = _p(1, 1000)


@dataclass(frozen=True)
class OutlineCueConfig:
    max_height_m: float = _p(0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class CueConfig:
    ground: GroundCueConfig
    crossing: CrossingCueConfig
    scale: ScaleCueConfig
    range_rate: RangeRateCueConfig
    motion: MotionCueConfig
    outline: OutlineCueConfig


@dataclass(frozen=True)
class HiddenConfig:
    keep_s: float = _p(0.0, 10.0)
    warn_s: float = _p(0.0, 10.0)
    max_level: int = _p(0, 2)


@dataclass(frozen=True)
class ObstacleConfig:
    max_range_m: float = _p(0.0, 200.0)
    memory_s: float = _p(0.0, 10.0)
    evidence_threshold: float = _p(0.0, 1e6, lo_open=True)


@dataclass(frozen=True)
class WarningConfig:
    ttc_caution_s: float = _p(0.0, 60.0, lo_open=True)
    ttc_warning_s: float = _p(0.0, 60.0, lo_open=True)
    corridor_margin_m: float = _p(0.0, 10.0)
    hysteresis_s: float = _p(0.0, 10.0)
    min_persistence_frames: int = _p(1, 1000)
    hold_s: float = _p(0.0, 60.0)
    horizon_s: float = _p(0.0, 60.0, lo_open=True)
    min_probability: float = _p(0.0, 1.0)
    min_height_m: float = _p(0.0, 10.0)


@dataclass(frozen=True)
class RuntimeConfig:
    seed: int = _p(0)
    out_dir: str = _p()
    record: bool = _p()
    record_dir: str = _p()
    record_rotate_s: float = _p(1.0)
    record_rotate_mb: float = _p(1.0)
    replay_rate: float = _p(0.0, 1.0, lo_open=True)


@dataclass(frozen=True)
class Config:
    camera: CameraConfig
    mount: MountConfig
    vehicle_can: VehicleCanConfig
    hmi_can: HmiCanConfig
    ptu: PtuConfig
    flow: FlowConfig
    detection: DetectionConfig
    refinement: RefinementConfig
    probability_map: ProbabilityMapConfig
    clustering: ClusteringConfig
    tracking: TrackingConfig
    cue: CueConfig
    hidden: HiddenConfig
    obstacle: ObstacleConfig
    warning: WarningConfig
    runtime: RuntimeConfig

    def digest(self) -> str:
        """Short SHA-256 of the effective configuration (for ``summary.json``)."""
        text = json.dumps(dataclasses.asdict(self), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_overrides(
        self, overrides: dict[str, dict[str, Any]], source: str = "<overrides>"
    ) -> Config:
        """A copy with ``{section: {key: value}}`` applied and validated like a file."""
        raw = dataclasses.asdict(self)
        origin: dict[str, str] = {}
        _merge(Config, raw, overrides, source, origin)
        built: Config = _build(Config, raw, origin, "<config>", "")
        return built


# ---------------------------------------------------------------- loading


def default_config_path() -> Path:
    return Path(str(resources.files(RESOURCES).joinpath("default.toml")))


def resource_path(name: str) -> Path:
    """Path of a file shipped in ``config/`` (DBCs, default.toml)."""
    return Path(str(resources.files(RESOURCES).joinpath(name)))


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; missing file or syntax error -> ConfigError naming it."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(p, "", "file not found") from None
    except IsADirectoryError:
        raise ConfigError(p, "", "is a directory, not a TOML file") from None
    except PermissionError:
        raise ConfigError(p, "", "permission denied") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(p, "", f"invalid TOML: {exc}") from None


def load_config(path: str | Path | None = None) -> Config:
    """The default configuration, with the keys of ``path`` (if given) overriding it."""
    default_path = default_config_path()
    raw: dict[str, Any] = {}
    origin: dict[str, str] = {}
    _merge(Config, raw, read_toml(default_path), str(default_path), origin)
    if path is not None:
        _merge(Config, raw, read_toml(path), str(path), origin)
    built: Config = _build(Config, raw, origin, str(default_path), "")
    return built


def _tables(cls: type) -> dict[str, type]:
    """The fields of a group of tables (``Config``, ``CueConfig``) that are tables themselves."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)
            if dataclasses.is_dataclass(hints[f.name])}


def _merge(cls: type, base: dict[str, Any], user: dict[str, Any], source: str,
           origin: dict[str, str], prefix: str = "") -> None:
    """Copy ``user``'s keys into ``base``, checking each against the schema ``cls``; remember
    in ``origin`` (dotted key -> file) where each came from."""
    tables = _tables(cls)
    known = {f.name for f in dataclasses.fields(cls)}
    for key, value in user.items():
        name = prefix + key
        if key not in known:
            if tables and len(tables) == len(known):
                raise ConfigError(source, name,
                                  f"unknown section (known: {', '.join(prefix + t for t in tables)})")
            raise ConfigError(source, name, "unknown key")
        if key in tables:
            if not isinstance(value, dict):
                raise ConfigError(source, name, "must be a table")
            _merge(tables[key], base.setdefault(key, {}), value, source, origin, name + ".")
        else:
            base[key] = value
            origin[name] = source


def _build(cls: type, raw: dict[str, Any], origin: dict[str, str], default: str,
           prefix: str) -> Any:
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        key = prefix + f.name
        typ = hints[f.name]
        if isinstance(typ, type) and dataclasses.is_dataclass(typ):
            kwargs[f.name] = _build(typ, raw.get(f.name, {}), origin, default, key + ".")
            continue
        src = origin.get(key, default)
        if f.name not in raw:
            raise ConfigError(src, key, "missing (not in the default configuration)")
        kwargs[f.name] = _check(raw[f.name], typ, f.metadata, src, key)
    built = cls(**kwargs)
    if cls is Config:
        _check_cross(built, origin)
    return built


def _check(value: Any, typ: Any, meta: Any, src: str, key: str) -> Any:
    origin_t = typing.get_origin(typ)
    if origin_t is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(src, key, f"expected a list of numbers, got {type(value).__name__}")
        items = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(src, key, f"expected a list of numbers, found {v!r}")
            items.append(float(v))
        return tuple(items)
    if origin_t in (Union, types.UnionType):
        raise TypeError(f"unsupported config type {typ}")
    if typ is bool:
        if not isinstance(value, bool):
            raise ConfigError(src, key, f"expected true or false, got {value!r}")
    elif typ is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(src, key, f"expected an integer, got {value!r}")
    elif typ is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(src, key, f"expected a number, got {value!r}")
        value = float(value)
        if math.isnan(value):
            raise ConfigError(src, key, "NaN is not allowed")
    elif typ is str and not isinstance(value, str):
        raise ConfigError(src, key, f"expected a string, got {value!r}")
    choices = meta.get("choices", ())
    if choices and value not in choices:
        raise ConfigError(src, key, f"{value!r} is not one of {', '.join(map(repr, choices))}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and (value <= lo if meta.get("lo_open") else value < lo):
        raise ConfigError(
            src,
            key,
            f"{value!r} is out of range (must be {'>' if meta.get('lo_open') else '>='} {lo})",
        )
    if hi is not None and value > hi:
        raise ConfigError(src, key, f"{value!r} is out of range (must be <= {hi})")
    if meta.get("path") and isinstance(value, str):
        p = Path(value).expanduser()
        if not p.is_absolute():
            base = Path(src).parent if Path(src).name else Path(".")
            p = base / p
        if not p.exists():
            raise ConfigError(src, key, f"file not found: {p}")
        value = str(p.resolve())
    return value


def _check_cross(cfg: Config, origin: dict[str, str]) -> None:
    def src(section: str, key: str) -> str:
        return origin.get(f"{section}.{key}", "<config>")

    if len(cfg.camera.distortion) not in (0, 4, 5, 8, 12, 14):
        raise ConfigError(
            src("camera", "distortion"),
            "camera.distortion",
            "needs 4, 5, 8, 12 or 14 coefficients (OpenCV k1 k2 p1 p2 [k3 ...])",
        )
    if cfg.warning.ttc_warning_s > cfg.warning.ttc_caution_s:
        raise ConfigError(
            src("warning", "ttc_warning_s"),
            "warning.ttc_warning_s",
            f"{cfg.warning.ttc_warning_s} must not exceed warning.ttc_caution_s "
            f"({cfg.warning.ttc_caution_s})",
        )
    if cfg.probability_map.gauss_window_px % 2 == 0:
        raise ConfigError(
            src("probability_map", "gauss_window_px"),
            "probability_map.gauss_window_px",
            f"{cfg.probability_map.gauss_window_px} must be odd",
        )
    if cfg.hmi_can.warning_id == cfg.hmi_can.status_id:
        raise ConfigError(
            src("hmi_can", "status_id"), "hmi_can.status_id", "must differ from hmi_can.warning_id"
        )
