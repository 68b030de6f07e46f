"""One recording of a batch: replayed (and evaluated) into its own output directory.

:func:`run_job` is what a batch worker runs, on Ray or in-process. It takes the same path
as ``collision-warning replay`` (the recording opened and validated, its ``meta.toml``
applied over the configuration, :func:`appliance.replay.replay`), so a recording's outputs
are the ones ``replay`` writes. It never raises for a bad recording: the result carries
the one-line error and the batch goes on.

A run directory whose ``summary.json`` (written last) names the same configuration and
code digests is a complete run of this code: it is not replayed again. Anything else there
is redone; the stale ``summary.json`` and evaluation go first, so a run killed while it is
redone never looks complete.
"""

from __future__ import annotations

import json
import os
import platform
import resource
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from appliance.code_digest import code_digest
from appliance.config import Config
from appliance.errors import ApplianceError
from appliance.evaluation.report import evaluate_run
from appliance.recording import Recording, apply_meta
from appliance.replay import replay

SUMMARY = "summary.json"
EVALUATION = ("evaluation.json", "timeline.png")  # evaluate_run writes them in this order


@dataclass(frozen=True)
class Job:
    """A recording (a path the worker can read) and its output directory (``OUT/<name>``)."""

    recording: str
    out_dir: str
    evaluate: bool

    @property
    def name(self) -> str:
        return Path(self.out_dir).name


@dataclass(frozen=True)
class JobResult:
    """What one recording gave: status, figures and what it cost the worker.

    ``status``: ``done`` (replayed now), ``skipped`` (a complete run was there) or
    ``failed`` (``error`` says why in one line, naming the file and line where known).
    Costs are None for a skipped replay. Times are ``time.time()`` on the worker's clock.
    """

    name: str
    recording: str
    out_dir: str
    status: str
    error: str | None = None
    frames: int | None = None
    replay_s: float | None = None
    cpu_s: float | None = None
    peak_rss_mb: float | None = None
    read_bytes: int | None = None
    recording_bytes: int | None = None
    evaluation: dict[str, Any] | None = None
    host: str = ""
    pid: int = 0
    started: float = 0.0
    finished: float = 0.0
    submitted: float | None = None  # set by the engine, on the driver's clock
    received: float | None = None


def _read_chars() -> int | None:
    """Bytes this process has read through system calls (``/proc/self/io`` rchar)."""
    try:
        with open("/proc/self/io") as fh:
            for line in fh:
                if line.startswith("rchar:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def peak_rss_mb() -> float:
    """The process's peak resident memory so far, MB (Linux reports ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _recording_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def complete_run(out_dir: Path, cfg: Config) -> dict[str, Any] | None:
    """The run's summary when ``out_dir`` holds a complete run of this configuration and code."""
    try:
        summary = json.loads((out_dir / SUMMARY).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(summary, dict):
        return None
    same = (summary.get("config_digest") == cfg.digest()
            and summary.get("code_digest") == code_digest())
    return summary if same else None


def _evaluation(job: Job, rec: Recording, redo: bool) -> dict[str, Any] | None:
    """The run's evaluation: the one on disk when complete and still valid, else made now."""
    if not job.evaluate or not (rec.path / "truth.json").is_file():
        return None
    out = Path(job.out_dir)
    if not redo and all((out / f).is_file() for f in EVALUATION):
        try:
            kept = json.loads((out / EVALUATION[0]).read_text())
            if isinstance(kept, dict):
                return kept
        except ValueError:
            pass
    return evaluate_run(rec.path, out)


def run_job(job: Job, cfg: Config) -> JobResult:
    """Replay ``job.recording`` into ``job.out_dir`` unless a complete run is there; evaluate
    it when asked and the recording has truth. Errors come back in the result."""
    started = time.time()
    cpu0, read0 = _cpu_s(), _read_chars()
    base = JobResult(name=job.name, recording=job.recording, out_dir=job.out_dir,
                     status="failed", host=platform.node(), pid=os.getpid(), started=started)
    stage = "replay"
    try:
        rec = Recording(job.recording, defaults=cfg)
        run_cfg = apply_meta(cfg, rec.meta)
        out = Path(job.out_dir)
        summary = complete_run(out, run_cfg)
        replay_s = None
        if summary is None:
            for stale in (SUMMARY, *EVALUATION):
                (out / stale).unlink(missing_ok=True)
            rec.validate()
            result = replay(rec, run_cfg, out)
            frames, replay_s = result.frames_processed, result.wall_s
        else:
            frames = int(summary["frames_processed"])
        stage = "evaluate"
        evaluation = _evaluation(job, rec, redo=summary is None)
    except ApplianceError as exc:
        return _failed(base, f"{stage}: {exc}" if stage != "replay" else str(exc))
    except Exception as exc:  # noqa: BLE001 - the last line of defence: the batch goes on
        return _failed(base, f"{stage}: internal error: {type(exc).__name__}: {exc}")
    read1 = _read_chars()
    return replace(
        base,
        status="done" if summary is None else "skipped",
        frames=frames,
        replay_s=None if replay_s is None else round(replay_s, 3),
        cpu_s=round(_cpu_s() - cpu0, 3) if summary is None else None,
        peak_rss_mb=round(peak_rss_mb(), 1),
        read_bytes=read1 - read0 if summary is None and read0 is not None and read1 is not None
        else None,
        recording_bytes=_recording_bytes(rec.path),
        evaluation=evaluation,
        finished=time.time(),
    )


def _failed(base: JobResult, error: str) -> JobResult:
    return replace(base, status="failed", error=error.splitlines()[0] if error else "failed",
                   peak_rss_mb=round(peak_rss_mb(), 1), finished=time.time())
