"""Configuration: defaults, user overrides, and each kind of error: exit 2 naming file and key."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from appliance.config import Config, load_config
from appliance.errors import ConfigError


def test_default_has_the_papers_values(default_config: Config) -> None:
    c = default_config
    assert c.detection.particles == 500
    assert c.flow.pyramid_levels == 2
    assert (c.tracking.position_std_px, c.tracking.velocity_std_px, c.tracking.process_std_px) == (
        7,
        2,
        2,
    )
    assert (c.warning.ttc_caution_s, c.warning.ttc_warning_s) == (3.0, 2.0)
    assert Path(c.vehicle_can.dbc).is_file() and Path(c.hmi_can.dbc).is_file()


def test_every_default_key_is_documented_with_a_comment() -> None:
    from appliance.config import default_config_path

    for line in default_config_path().read_text().splitlines():
        if "=" in line and not line.lstrip().startswith("#"):
            assert "#" in line, f"undocumented default: {line}"


def test_user_file_overrides_only_its_keys(tmp_path: Path, default_config: Config) -> None:
    f = tmp_path / "user.toml"
    f.write_text("[detection]\nparticles = 200\n[ptu]\nenabled = false\n")
    c = load_config(f)
    assert c.detection.particles == 200 and c.ptu.enabled is False
    assert c.detection.sigma_e_px == default_config.detection.sigma_e_px
    assert c.camera == default_config.camera
    assert c.digest() != default_config.digest()


def test_relative_dbc_resolves_against_the_user_file(tmp_path: Path) -> None:
    (tmp_path / "car.dbc").write_text((Path(load_config().vehicle_can.dbc)).read_text())
    f = tmp_path / "user.toml"
    f.write_text('[vehicle_can]\ndbc = "car.dbc"\n')
    assert load_config(f).vehicle_can.dbc == str((tmp_path / "car.dbc").resolve())


@pytest.mark.parametrize(
    "text, key, problem",
    [
        ("[detection]\nparticels = 3\n", "detection.particels", "unknown key"),
        ("[detectoin]\nparticles = 3\n", "detectoin", "unknown section"),
        ('[detection]\nparticles = "many"\n', "detection.particles", "expected an integer"),
        ("[detection]\nparticles = 2.5\n", "detection.particles", "expected an integer"),
        ("[ptu]\nenabled = 1\n", "ptu.enabled", "expected true or false"),
        ("[detection]\nparticles = 0\n", "detection.particles", "out of range"),
        ("[camera]\nfx = -1.0\n", "camera.fx", "out of range"),
        ("[flow]\nfb_threshold_px = nan\n", "flow.fb_threshold_px", "NaN"),
        ('[detection]\nlikelihood = "angle"\n', "detection.likelihood", "is not one of"),
        ('[vehicle_can]\ndbc = "nope.dbc"\n', "vehicle_can.dbc", "file not found"),
        ("[warning]\nttc_warning_s = 4.0\n", "warning.ttc_warning_s", "must not exceed"),
        ("[probability_map]\ngauss_window_px = 30\n", "probability_map.gauss_window_px", "odd"),
        ("[cue.ground]\ncoast_s = -1.0\n", "cue.ground.coast_s", "out of range"),
        ("[cue.groudn]\ncoast_s = 1.0\n", "cue.groudn", "unknown section"),
        ("[cue.ground]\ncoast = 1.0\n", "cue.ground.coast", "unknown key"),
        ("[cue]\nground = 1.0\n", "cue.ground", "must be a table"),
        ('[camera]\ndistortion = [0.1, "x"]\n', "camera.distortion", "list of numbers"),
        ("[detection\n", "", "invalid TOML"),
    ],
)
def test_errors_name_file_key_and_problem(
    tmp_path: Path, text: str, key: str, problem: str
) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(f)
    msg = str(info.value)
    assert str(f) in msg and key in msg and problem in msg, msg
    assert "\n" not in msg


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="file not found"):
        load_config(tmp_path / "absent.toml")


def test_config_is_frozen(default_config: Config) -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        default_config.detection.particles = 3  # type: ignore[misc]


def test_with_overrides_validates(default_config: Config) -> None:
    c = default_config.with_overrides({"detection": {"particles": 64}})
    assert c.detection.particles == 64
    c = default_config.with_overrides({"cue": {"scale": {"min_frames": 7}}})
    assert c.cue.scale.min_frames == 7 and c.cue.ground == default_config.cue.ground
    with pytest.raises(ConfigError, match="detection.particles"):
        default_config.with_overrides({"detection": {"particles": -1}})


def test_command_line_exits_2_with_one_line(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text("[detection]\nparticles = -5\n")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "appliance",
            "replay",
            str(tmp_path),
            "--out",
            str(tmp_path / "o"),
            "--config",
            str(f),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "detection.particles" in r.stderr and str(f) in r.stderr
    assert "Traceback" not in r.stderr
