"""``collision-warning batch`` on a local Ray with two workers.

One simulated drive (a lead car braking, 3 s: tracks and warnings), a copy of it under
another name and a copy with ``frames.csv`` cut mid-line. The batch's outputs are compared
byte for byte with ``collision-warning replay`` of the same drive; the damaged one fails
alone; a second batch over the same output directory skips the complete run and redoes the
one that was cut short.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from appliance.batch.cli import expand
from appliance.batch.task import complete_run
from appliance.cli import main
from appliance.code_digest import code_digest
from appliance.config import Config
from appliance.sim.drive import simulate

pytest.importorskip("ray")

RUN_FILES = ("warnings.jsonl", "tracks.jsonl", "egomotion.csv", "can_out.log")


@pytest.fixture(scope="module")
def ray_tmp() -> Iterator[None]:
    """Ray's session files in a short private directory (its socket paths have a length limit)."""
    tmp = tempfile.mkdtemp(prefix="ray")
    mp = pytest.MonkeyPatch()
    mp.setenv("RAY_TMPDIR", tmp)
    yield
    mp.undo()
    shutil.rmtree(tmp, ignore_errors=True)


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("drives")
    lead = simulate("lead_car_braking", root / "recs" / "lead", seed=1, duration=3.0)
    copy = root / "recs" / "lead-copy"
    shutil.copytree(lead, copy)
    damaged = root / "recs" / "damaged"
    shutil.copytree(lead, damaged)
    text = (damaged / "frames.csv").read_text()
    (damaged / "frames.csv").write_text(text[: len(text) // 2].rsplit(",", 1)[0] + ",\n")
    ref = root / "ref"
    assert main(["replay", str(lead), "--out", str(ref), "--no-progress"]) == 0
    return {"lead": Path(lead), "copy": copy, "damaged": damaged, "ref": ref, "root": root}


@pytest.fixture(scope="module")
def first_batch(drives: dict[str, Path], ray_tmp: None) -> dict[str, object]:
    out = drives["root"] / "batch"
    rc, text = _run_batch(["batch", str(drives["root"] / "recs"), "--out", str(out),
                           "--workers", "2", "--evaluate"])
    return {"rc": rc, "stdout": text, "out": out,
            "doc": json.loads((out / "batch.json").read_text())}


def _run_batch(argv: list[str]) -> tuple[int, str]:
    """``main(argv)`` with its standard output captured (module fixtures have no capsys)."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(argv)
    return rc, buf.getvalue()


def test_outputs_are_those_of_replay(drives: dict[str, Path], first_batch: dict[str, object]) -> None:
    out = first_batch["out"]
    assert isinstance(out, Path)
    for name in ("lead", "lead-copy"):
        for f in RUN_FILES:
            assert (out / name / f).read_bytes() == (drives["ref"] / f).read_bytes(), (name, f)
    ref_tracks = (drives["ref"] / "tracks.jsonl").read_text()
    assert '"id"' in ref_tracks and (drives["ref"] / "warnings.jsonl").read_text()


def test_a_damaged_recording_fails_alone(first_batch: dict[str, object]) -> None:
    assert first_batch["rc"] == 1
    doc = first_batch["doc"]
    assert isinstance(doc, dict)
    runs = {r["name"]: r for r in doc["runs"]}
    assert [runs[n]["status"] for n in ("damaged", "lead", "lead-copy")] == [
        "failed", "done", "done"]
    error = runs["damaged"]["error"]
    assert "frames.csv:" in error and "\n" not in error
    row = next(line for line in str(first_batch["stdout"]).splitlines()
               if line.startswith("damaged "))
    assert "failed" in row and error in row
    # the others were evaluated, pooled, costed and plotted
    assert runs["lead"]["evaluation"]["scenario"] == "lead_car_braking"
    assert runs["lead"]["cpu_s"] > 0 and runs["lead"]["frames"] == 91
    assert doc["pooled"]["all"]["runs"] == "2/3"
    assert doc["ray"]["workers"] == 2 and doc["ray"]["cpus"] == 2
    out = first_batch["out"]
    assert isinstance(out, Path)
    assert (out / "batch.png").stat().st_size > 0
    assert (out / "lead" / "evaluation.json").is_file()


def test_a_killed_batch_resumes(drives: dict[str, Path], first_batch: dict[str, object]) -> None:
    out = first_batch["out"]
    assert isinstance(out, Path)
    done_summary = (out / "lead" / "summary.json").read_bytes()
    done_mtime = (out / "lead" / "tracks.jsonl").stat().st_mtime_ns
    # lead-copy as a kill leaves it: rows half written, no summary.json
    cut = out / "lead-copy" / "tracks.jsonl"
    cut.write_bytes(cut.read_bytes()[:1000])
    (out / "lead-copy" / "summary.json").unlink()
    rc, text = _run_batch(["batch", str(drives["lead"]), str(drives["copy"]), "--out", str(out),
                           "--workers", "2", "--evaluate"])
    assert rc == 0, text
    runs = {r["name"]: r for r in json.loads((out / "batch.json").read_text())["runs"]}
    assert runs["lead"]["status"] == "skipped" and runs["lead-copy"]["status"] == "done"
    assert (out / "lead" / "summary.json").read_bytes() == done_summary
    assert (out / "lead" / "tracks.jsonl").stat().st_mtime_ns == done_mtime
    assert runs["lead"]["evaluation"] == json.loads(
        (out / "lead" / "evaluation.json").read_text())
    for f in RUN_FILES:
        assert (out / "lead-copy" / f).read_bytes() == (drives["ref"] / f).read_bytes(), f


def test_a_run_of_another_configuration_or_code_is_not_complete(
    tmp_path: Path, default_config: Config
) -> None:
    summary = {"config_digest": default_config.digest(), "code_digest": code_digest(),
               "frames_processed": 3}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    assert complete_run(tmp_path, default_config) == summary
    other = default_config.with_overrides({"warning": {"ttc_warning_s": 1.2}})
    assert complete_run(tmp_path, other) is None
    (tmp_path / "summary.json").write_text(json.dumps({**summary, "code_digest": "0" * 16}))
    assert complete_run(tmp_path, default_config) is None
    (tmp_path / "summary.json").write_text(json.dumps(summary)[:20])  # cut while written
    assert complete_run(tmp_path, default_config) is None


def test_without_ray_batch_says_how_to_install_it(
    drives: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    assert main(["batch", str(drives["lead"]), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'collision-warning[fleet]'" in err
    assert not (tmp_path / "out").exists()


def test_bad_arguments_exit_2_with_one_line(
    drives: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "elsewhere" / "lead"
    shutil.copytree(drives["lead"], other)
    assert main(["batch", str(drives["lead"]), str(other), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "same name" in err and str(other) in err
    assert main(["batch", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "nope: not a recording directory" in capsys.readouterr().err
    assert main(["batch", "x", "--out", str(tmp_path / "o"), "--address", "host"]) == 2
    assert "--address 'host'" in capsys.readouterr().err
    assert main(["batch", str(drives["lead"]), "--out", str(tmp_path / "o"),
                 "--workers", "0"]) == 2
    assert "--workers 0" in capsys.readouterr().err


def test_a_directory_of_recordings_stands_for_them(drives: dict[str, Path]) -> None:
    recs = drives["root"] / "recs"
    assert expand([str(recs)]) == [str(recs / n) for n in ("damaged", "lead", "lead-copy")]
    assert expand([str(drives["lead"])]) == [str(drives["lead"])]
    assert expand(["/not/here"]) == ["/not/here"]
