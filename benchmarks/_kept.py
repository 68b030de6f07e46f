"""Which kept recordings still come from the generator that would make them now.

``--keep DIR`` reuses recordings; a recording made by an older simulator is not the drive a
fresh checkout would replay, and a results page built on it does not reproduce. Each world's
``DIR/<world>/generated.json`` names, per recording, the digest of the generator that made it
(:func:`own_generator` for the appliance's simulator, :func:`kitti_generator` for the
kitti-street world). A kept recording without that digest, or with another one, is made again,
and its kept run is dropped with it (a run is reused by code and configuration only).
"""

from __future__ import annotations

import hashlib
import importlib
import json
import pkgutil
import shutil
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from appliance.config import resource_path

MANIFEST = "generated.json"


def files_digest(files: Iterable[tuple[str, Path]]) -> str:
    """Short SHA-256 over (name, file) pairs: each name and its file's content, by name."""
    h = hashlib.sha256()
    for name, path in sorted(set(files)):
        h.update(f"{name}\0".encode())
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def own_generator() -> str:
    """The appliance simulator's digest (:func:`own_generator_files`)."""
    return files_digest(own_generator_files())


def own_generator_files() -> list[tuple[str, Path]]:
    """(module name or resource, file) of everything the appliance's simulator reads: every
    appliance module it imports, the default configuration and the vehicle DBC. Listed by a
    fresh interpreter, so that what this process has imported does not count."""
    p = subprocess.run([sys.executable, "-m", "benchmarks._kept"], capture_output=True,
                       text=True, check=True)
    return [(name, Path(path)) for name, path in json.loads(p.stdout)]


def _imported_by_simulator() -> list[tuple[str, str]]:
    import appliance.sim as sim

    for m in pkgutil.iter_modules(sim.__path__):
        importlib.import_module(f"{sim.__name__}.{m.name}")
    files = [(name, str(mod.__file__)) for name, mod in list(sys.modules.items())
             if name.split(".")[0] == "appliance" and getattr(mod, "__file__", None)]
    return files + [(n, str(resource_path(n))) for n in ("default.toml", "vehicle.dbc")]


def kitti_generator(world: Path, extra: Iterable[Path] = ()) -> str:
    """The kitti-street world's digest: its Python sources and ego-motion data, and the
    scenarios ``extra`` registers in it."""
    files = [(p.relative_to(world).as_posix(), p) for p in world.rglob("*")
             if p.is_file() and "__pycache__" not in p.parts
             and (p.suffix == ".py" or p.relative_to(world).parts[0] == "data")]
    return files_digest([*files, *((p.name, p) for p in extra)])


def read_manifest(world_dir: Path) -> dict[str, str]:
    try:
        doc = json.loads((world_dir / MANIFEST).read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in doc.items()} if isinstance(doc, dict) else {}


def drop_stale(world_dir: Path, names: Iterable[str], digest: str) -> list[str]:
    """Remove the kept recordings (and their runs) among ``names`` that another generator
    made, or that no manifest vouches for; returns their names. Recordings not kept are left
    to be made."""
    made = read_manifest(world_dir)
    stale = []
    for name in names:
        rec = world_dir / "recordings" / name
        if not rec.exists() or made.get(name) == digest:
            continue
        shutil.rmtree(rec, ignore_errors=True)
        shutil.rmtree(world_dir / "runs" / name, ignore_errors=True)
        stale.append(name)
    return stale


def record(world_dir: Path, names: Iterable[str], digest: str) -> None:
    """Name ``digest`` as the generator of the recordings among ``names`` that now exist."""
    made = read_manifest(world_dir)
    for name in names:
        if (world_dir / "recordings" / name / "truth.json").is_file():
            made[name] = digest
    world_dir.mkdir(parents=True, exist_ok=True)
    (world_dir / MANIFEST).write_text(json.dumps(made, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    print(json.dumps(_imported_by_simulator()))
