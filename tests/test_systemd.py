"""The systemd unit and its companions are valid and carry what the appliance relies on."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
UNIT = ROOT / "systemd" / "collision-warning.service"


def _unit() -> configparser.ConfigParser:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.optionxform = str  # type: ignore[assignment,method-assign]
    cp.read_string(UNIT.read_text())
    return cp


def test_unit_has_the_directives_the_appliance_relies_on() -> None:
    svc = _unit()["Service"]
    assert svc["Type"] == "notify"
    assert svc["Restart"] == "on-failure"
    assert svc["WatchdogSec"]
    assert svc["User"] == "collision-warning"
    assert svc["ProtectSystem"] == "strict"
    assert svc["StateDirectory"] == "collision-warning"
    assert "run --config" in svc["ExecStart"]


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed")
def test_systemd_analyze_verify_is_clean(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("collision-warning")
    if not exe.exists():
        pytest.skip(f"console script not installed next to {sys.executable}")
    unit = tmp_path / "collision-warning.service"
    unit.write_text(
        UNIT.read_text().replace("/opt/collision-warning/.venv/bin/collision-warning", str(exe))
    )
    r = subprocess.run(
        ["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=60
    )
    complaints = [
        ln
        for ln in (r.stdout + r.stderr).splitlines()
        if unit.name in ln or "collision-warning" in ln
    ]
    assert r.returncode == 0 and not complaints, r.stdout + r.stderr


def test_network_file_sets_a_bitrate() -> None:
    cp = configparser.ConfigParser()
    cp.read(ROOT / "systemd" / "80-can0.network")
    assert cp["Match"]["Name"] == "can0" and cp["CAN"]["BitRate"]


def test_udev_rules_give_stable_names() -> None:
    text = (ROOT / "systemd" / "70-collision-warning.rules").read_text()
    assert 'SYMLINK+="cw-camera"' in text and 'SYMLINK+="cw-ptu"' in text


def test_example_config_loads() -> None:
    from appliance.config import load_config

    cfg = load_config(ROOT / "systemd" / "config.example.toml")
    assert cfg.camera.device == "/dev/cw-camera" and cfg.ptu.port == "/dev/cw-ptu"
