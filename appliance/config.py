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
    reopen_min_s: float = _p(0.0, lo_open=True)
    reopen_max_s: float = _p(0.0, lo_open=True)
    late_factor: float = _p(1.0)
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
    reopen_min_s: float = _p(0.0, lo_open=True)
    reopen_max_s: float = _p(0.0, lo_open=True)


@dataclass(frozen=True)
class HmiCanConfig:
    interface: str = _p()
    channel: str = _p()
    dbc: str = _p(path=True)
    warning_id: int = _p(0, 0x7FF)
    status_id: int = _p(0, 0x7FF)
    period_s: float = _p(0.0, 10.0, lo_open=True)
    tx_queue: int = _p(1, 100000)
    reopen_min_s: float = _p(0.0, lo_open=True)
    reopen_max_s: float = _p(0.0, lo_open=True)


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
    retries: int = _p(0, 10)
    fault_after: int = _p(1, 1000)
    speed_rad_s: float = _p(0.0, 10.0, lo_open=True)
    reopen_min_s: float = _p(0.0, lo_open=True)
    reopen_max_s: float = _p(0.0, lo_open=True)


@dataclass(frozen=True)
class FlowConfig:
    pyramid_levels: int = _p(0, 6)
    window_px: int = _p(3, 63)
    fb_threshold_px: float = _p(0.0, lo_open=True)
    rotation_guess: bool = _p()


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
    evidence_particles: float = _p(0.0, 1000.0)
    rotation_compensation: bool = _p()


@dataclass(frozen=True)
class ClusteringConfig:
    threshold: float = _p(0.0, 1.0, lo_open=True)
    dilation_px: int = _p(0, 255)
    min_correspondences: int = _p(1, 100000)
    member_weight: float = _p(0.0, 1.0)


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
    box_size_alpha: float = _p(0.0, 1.0, lo_open=True)
    reacquire_s: float = _p(0.0, 10.0)
    reacquire_gate_sigmas: float = _p(0.0, lo_open=True)
    reacquire_gate_m: float = _p(0.0, lo_open=True)
    reacquire_moving_only: bool = _p()
    coast_warn_s: float = _p(0.0, 10.0)
    coast_cover_ratio: float = _p(0.0, 10.0)
    coast_cover_frames: int = _p(1, 100)
    coast_course_ratio: float = _p(0.0, 1.0, lo_open=True)
    coast_course_points: float = _p(0.0, 1000.0)
    coast_course_seen_points: float = _p(0.0, 1000.0)
    coast_course_fraction: float = _p(0.0, 1.0)
    coast_bearing_std_px: float = _p(0.0, 100.0)
    outline_max_height_m: float = _p(0.0, 10.0)
    outline_tolerance: float = _p(0.0, 10.0, lo_open=True)


@dataclass(frozen=True)
class GroundConfig:
    contact_std_px: float = _p(0.0, 100.0, lo_open=True)
    pitch_std_rad: float = _p(0.0, 0.5)
    pitch_decay_s: float = _p(0.0, 100.0, lo_open=True)
    process_accel_m_s2: float = _p(0.0, lo_open=True)
    accel_std_m_s2: float = _p(0.0, 20.0)
    accel_time_constant_s: float = _p(0.0, 100.0)
    accel_min_speed_m_s: float = _p(0.0, 100.0)
    initial_velocity_std_m_s: float = _p(0.0, 100.0, lo_open=True)
    max_range_m: float = _p(1.0, 1000.0)
    coast_s: float = _p(0.0, 10.0)
    border_margin_px: int = _p(0, 1000)
    scale_ttc_min_frames: int = _p(2, 1000)
    scale_process_std: float = _p(0.0, 100.0)
    gate_sigmas: float = _p(0.0, 100.0, lo_open=True)
    memory_s: float = _p(0.0, 1000.0)
    bearing_rate_std_rad_s: float = _p(0.0, 10.0)
    bearing_window_s: float = _p(0.0, 10.0)
    bearing_min_width_fraction: float = _p(0.0, 1.0)
    bearing_min_frames: int = _p(3, 1000)
    scale_from_outline: bool = _p()
    range_rate_from_scale: bool = _p()
    range_rate_std_gain: float = _p(0.0, 100.0, lo_open=True)
    foot_halo_correction: bool = _p()


@dataclass(frozen=True)
class WarningConfig:
    ttc_caution_s: float = _p(0.0, 60.0, lo_open=True)
    ttc_warning_s: float = _p(0.0, 60.0, lo_open=True)
    corridor_margin_m: float = _p(0.0, 10.0)
    hysteresis_s: float = _p(0.0, 10.0)
    min_persistence_frames: int = _p(1, 1000)
    hold_s: float = _p(0.0, 60.0)
    corridor_hysteresis_m: float = _p(0.0, 10.0)
    horizon_s: float = _p(0.0, 60.0, lo_open=True)
    bearing_tolerance_rad: float = _p(0.0, 1.0)
    min_speed_m_s: float = _p(0.0, 50.0)
    moving_sigmas: float = _p(0.0, 100.0)
    moving_min_frames: int = _p(1, 1000)
    min_probability: float = _p(0.0, 1.0)
    fast_mover_m_s: float = _p(0.0, 100.0)
    coast_min_probability: float = _p(0.0, 1.0)
    coast_max_level: int = _p(0, 2)
    pool_covered_tracks: bool = _p()
    min_height_m: float = _p(0.0, 10.0)
    velocity_significance_sigmas: float = _p(0.0, 100.0)
    velocity_conditioning: bool = _p()
    acceleration_significance_sigmas: float = _p(0.0, 100.0)


@dataclass(frozen=True)
class RuntimeConfig:
    frame_buffer: int = _p(1, 1000)
    can_buffer: int = _p(1, 1_000_000)
    ptu_buffer: int = _p(1, 1_000_000)
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
    ground: GroundConfig
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
        _merge(raw, overrides, source, {})
        return _build(raw, {s: {k: source for k in v} for s, v in overrides.items()}, None)


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
    raw = read_toml(default_path)
    origin: dict[str, dict[str, str]] = {
        s: {k: str(default_path) for k in v} for s, v in raw.items()
    }
    if path is not None:
        _merge(raw, read_toml(path), str(path), origin)
    return _build(raw, origin, default_path)


def _merge(
    base: dict[str, Any], user: dict[str, Any], source: str, origin: dict[str, dict[str, str]]
) -> None:
    sections = {f.name: f.type for f in dataclasses.fields(Config)}
    for section, values in user.items():
        if section not in sections:
            raise ConfigError(source, section, f"unknown section (known: {', '.join(sections)})")
        if not isinstance(values, dict):
            raise ConfigError(source, section, "must be a table")
        known = {f.name for f in dataclasses.fields(_section_types()[section])}
        for key, value in values.items():
            if key not in known:
                raise ConfigError(source, f"{section}.{key}", "unknown key")
            base.setdefault(section, {})[key] = value
            origin.setdefault(section, {})[key] = source


def _section_types() -> dict[str, type]:
    hints = typing.get_type_hints(Config)
    return {f.name: hints[f.name] for f in dataclasses.fields(Config)}


def _build(
    raw: dict[str, Any], origin: dict[str, dict[str, str]], default_path: Path | None
) -> Config:
    sections: dict[str, Any] = {}
    for name, cls in _section_types().items():
        values = raw.get(name, {})
        hints = typing.get_type_hints(cls)
        kwargs: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            key = f"{name}.{f.name}"
            src = origin.get(name, {}).get(f.name, str(default_path or "<config>"))
            if f.name not in values:
                raise ConfigError(src, key, "missing (not in the default configuration)")
            kwargs[f.name] = _check(values[f.name], hints[f.name], f.metadata, src, key)
        sections[name] = cls(**kwargs)
    cfg = Config(**sections)
    _check_cross(cfg, origin)
    return cfg


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


def _check_cross(cfg: Config, origin: dict[str, dict[str, str]]) -> None:
    def src(section: str, key: str) -> str:
        return origin.get(section, {}).get(key, "<config>")

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
    for section in ("camera", "vehicle_can", "hmi_can", "ptu"):
        sec = getattr(cfg, section)
        if sec.reopen_max_s < sec.reopen_min_s:
            raise ConfigError(
                src(section, "reopen_max_s"),
                f"{section}.reopen_max_s",
                f"must be >= {section}.reopen_min_s",
            )
