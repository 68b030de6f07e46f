"""``pip install .`` (README, "Install in a vehicle") installs every package of the appliance."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_directory_is_listed_in_pyproject() -> None:
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(setuptools["packages"])
    found = {p.parent.relative_to(ROOT).as_posix().replace("/", ".")
             for top in ("appliance", "drivers") for p in (ROOT / top).rglob("__init__.py")}
    assert {"appliance", "appliance.decision", "drivers"} <= found
    assert found - listed == set(), "packages a non-editable install would leave out"
