"""Where a batch runs: Ray (a local instance, or a cluster by address), or in this process.

Each recording is one Ray task of one CPU (:func:`appliance.batch.task.run_job`); OpenCV is
held to one thread in it, the CPU the task reserved. A task whose worker dies (killed, out
of memory, node lost) is retried once, then reported as failed with Ray's one-line reason.
Ray is an optional extra: without it :func:`run_on_ray` raises :class:`RayMissing`.
"""

from __future__ import annotations

import logging
import os
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from appliance.batch.task import Job, JobResult, run_job
from appliance.config import Config
from appliance.errors import RuntimeFailure, UsageError

INSTALL_HINT = "pip install 'collision-warning[fleet]'"
# "auto", "ray://host:port" (Ray client) or "host:port" (a cluster's GCS, from one of its nodes)
ADDRESS = re.compile(r"^(auto|ray://[^\s:/]+:\d+|[^\s:/]+:\d+)$")
TASK_RETRIES = 1


class RayMissing(UsageError):
    def __init__(self) -> None:
        super().__init__(f"Ray is not installed; install the fleet extra: {INSTALL_HINT}")


@dataclass(frozen=True)
class Cluster:
    """A local Ray with ``workers`` CPUs (``address`` None), or the cluster at ``address``
    with at most ``workers`` recordings in flight (None: as many as it has CPUs)."""

    address: str | None = None
    workers: int | None = None

    def __post_init__(self) -> None:
        if self.workers is not None and self.workers < 1:
            raise UsageError(f"--workers {self.workers}: must be at least 1")
        if self.address is not None and not ADDRESS.match(self.address):
            raise UsageError(f"--address {self.address!r}: expected auto, ray://HOST:PORT "
                             "or HOST:PORT")


@dataclass(frozen=True)
class RayInfo:
    """What the batch ran on: Ray's version, the cluster's CPUs and nodes, start-up time."""

    version: str
    address: str
    cpus: float
    nodes: int
    startup_s: float


OnResult = Callable[[JobResult], None]


def require_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise RayMissing() from None
    return ray


def _ray_task(job: Job, cfg: Config) -> JobResult:
    """The Ray task: one recording on the one CPU Ray reserved for it."""
    import cv2

    cv2.setNumThreads(1)
    return run_job(job, cfg)


def warm() -> int:
    """A task that only loads the appliance into a worker (done when this module is loaded)."""
    return os.getpid()


def connect(cluster: Cluster) -> RayInfo:
    """Start a local Ray or join the cluster; the caller shuts it down (:func:`disconnect`).

    A local Ray's workers load the appliance before this returns, so its start-up time
    is the time until the first recording can start, and the first task on a worker costs
    what the others do.
    """
    ray = require_ray()
    t0 = time.perf_counter()
    try:
        if cluster.address is None:
            ray.init(address="local", num_cpus=cluster.workers, include_dashboard=False,
                     log_to_driver=False, logging_level=logging.WARNING)
        else:
            ray.init(address=cluster.address, log_to_driver=False,
                     logging_level=logging.WARNING)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        where = cluster.address or "a local Ray"
        raise RuntimeFailure(f"cannot start or join {where}: {str(exc).splitlines()[0]}") from None
    if cluster.address is None:
        load = ray.remote(num_cpus=1)(warm)
        ray.get([load.remote() for _ in range(cluster.workers or 1)])
    resources = ray.cluster_resources()
    return RayInfo(version=ray.__version__, address=cluster.address or "local",
                   cpus=float(resources.get("CPU", 0.0)),
                   nodes=len([n for n in ray.nodes() if n.get("Alive")]),
                   startup_s=round(time.perf_counter() - t0, 3))


def disconnect() -> None:
    ray = require_ray()
    if ray.is_initialized():
        ray.shutdown()


def _ray_failure(job: Job, exc: Exception, submitted: float) -> JobResult:
    reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return JobResult(name=job.name, recording=job.recording, out_dir=job.out_dir,
                     status="failed", error=f"Ray: {type(exc).__name__}: {reason}",
                     submitted=submitted, received=time.time())


def run_on_ray(jobs: Sequence[Job], cfg: Config, cluster: Cluster,
               on_result: OnResult | None = None) -> list[JobResult]:
    """Every job as one Ray task on the connected Ray; results in the order of ``jobs``.

    ``on_result`` sees each result as it arrives (the progress bar). On a cluster with
    ``workers`` given, no more than that many tasks are in flight at once; otherwise two per
    CPU (one running, one queued behind it), so that the driver's bookkeeping stays small
    however many recordings there are.
    """
    ray = require_ray()
    remote = ray.remote(num_cpus=1, max_retries=TASK_RETRIES)(_ray_task)
    cfg_ref = ray.put(cfg)
    if cluster.address is not None and cluster.workers is not None:
        cap = cluster.workers
    else:
        cap = 2 * max(1, int(ray.cluster_resources().get("CPU", 1)))
    results: list[JobResult | None] = [None] * len(jobs)
    pending: dict[Any, tuple[int, float]] = {}
    queue = list(range(len(jobs)))
    queue.reverse()
    while queue or pending:
        while queue and len(pending) < cap:
            i = queue.pop()
            pending[remote.remote(jobs[i], cfg_ref)] = (i, time.time())
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            i, submitted = pending.pop(ref)
            try:
                res = replace(ray.get(ref), submitted=submitted, received=time.time())
            except ray.exceptions.RayError as exc:
                res = _ray_failure(jobs[i], exc, submitted)
            results[i] = res
            if on_result is not None:
                on_result(res)
    return [r for r in results if r is not None]


def run_in_process(jobs: Sequence[Job], cfg: Config,
                   on_result: OnResult | None = None) -> list[JobResult]:
    """Every job one after another in this process (no Ray): the sequential reference."""
    results = []
    for job in jobs:
        submitted = time.time()
        res = replace(run_job(job, cfg), submitted=submitted, received=time.time())
        results.append(res)
        if on_result is not None:
            on_result(res)
    return results
