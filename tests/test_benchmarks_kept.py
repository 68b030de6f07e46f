"""Kept benchmark recordings are reused only while the generator that made them is unchanged."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks import _kept


def _recording(world_dir: Path, name: str) -> Path:
    rec = world_dir / "recordings" / name
    rec.mkdir(parents=True)
    (rec / "truth.json").write_text("{}")
    run = world_dir / "runs" / name
    run.mkdir(parents=True)
    (run / "summary.json").write_text("{}")
    return rec


def test_recordings_of_another_generator_are_dropped_with_their_runs(tmp_path: Path) -> None:
    world = tmp_path / "own"
    for name in ("same", "older", "unnamed"):
        _recording(world, name)
    _kept.record(world, ["same", "older", "not-made"], "aaaa")
    assert json.loads((world / _kept.MANIFEST).read_text()) == {"older": "aaaa", "same": "aaaa"}
    manifest = _kept.read_manifest(world)
    manifest["older"] = "bbbb"
    (world / _kept.MANIFEST).write_text(json.dumps(manifest))

    stale = _kept.drop_stale(world, ["same", "older", "unnamed", "not-made"], "aaaa")

    assert sorted(stale) == ["older", "unnamed"]
    assert (world / "recordings" / "same" / "truth.json").is_file()
    assert (world / "runs" / "same").is_dir()
    for name in ("older", "unnamed"):
        assert not (world / "recordings" / name).exists()
        assert not (world / "runs" / name).exists()


def test_the_own_generator_is_the_simulator_not_the_detector() -> None:
    names = {name for name, _ in _kept.own_generator_files()}
    assert {"appliance.sim.render", "appliance.sim.scenarios", "appliance.vision.geometry",
            "vehicle.dbc", "default.toml"} <= names
    # a change to the detector or the decision replays the kept drives, it does not remake them
    assert not any(n.startswith(("appliance.decision", "appliance.pipeline")) for n in names)
    # whatever this process has imported (the detector, here) does not count
    import appliance.pipeline  # noqa: F401

    assert _kept.own_generator() == _kept.own_generator()
    assert _kept.own_generator() == _kept.files_digest(_kept.own_generator_files())


def test_a_changed_world_source_or_data_file_changes_its_digest(tmp_path: Path) -> None:
    world = tmp_path / "world"
    (world / "data").mkdir(parents=True)
    (world / "generate.py").write_text("print('v1')\n")
    (world / "data" / "poses.txt").write_text("0 0 0\n")
    (world / "notes.md").write_text("not read by the generator\n")
    extra = tmp_path / "hook.py"
    extra.write_text("MOVERS = 1\n")
    first = _kept.kitti_generator(world, [extra])
    (world / "notes.md").write_text("edited\n")
    assert _kept.kitti_generator(world, [extra]) == first
    for path, text in ((world / "data" / "poses.txt", "0 0 1\n"),
                       (world / "generate.py", "print('v2')\n"), (extra, "MOVERS = 2\n")):
        before = _kept.kitti_generator(world, [extra])
        path.write_text(text)
        assert _kept.kitti_generator(world, [extra]) != before
