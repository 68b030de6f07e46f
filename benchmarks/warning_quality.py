"""Warning quality over every simulated scenario of two worlds: ``python -m benchmarks
warning_quality [--world own|kitti-street|both]``.

Worlds: ``own`` is the appliance's simulator (``collision-warning simulate``), scored by
``appliance.evaluation.report``; ``kitti-street`` is the independent world of
``../shared/worlds/kitti-street`` (``--ks-world``), generated and scored by its own
``generate.py`` and ``score.py`` (``benchmarks/_kitti_street.py`` maps its scores to these
columns). For each world, scenario and seed: the recording is made once, then every
recording of the selected worlds is replayed in one batch on Ray
(``appliance.batch``, ``--jobs`` workers), then scored. It prints, per world, one row per
run and one per scenario over its seeds, the pooled figures, and a table pooled per world:

* collision scenarios: level 2 at least 1.5 s before ``collision_t`` (aim 2.0 s);
* no-collision scenarios: no level-2 warning, at most one level-1 per minute;
* a mover is a confirmed track within 10 frames of being >= 15 px tall, visible and moving
  over the ground (> 0.3 m/s);
* median relative TTC error <= 20 % and distance error <= 15 % in the last 3 s;
* ghost tracks (confirmed tracks never on a mover, no target) per minute (own world only);
* what kept the level 2 from being in time, both worlds: the colliding object's frames 3.5-1.5 s
  before contact by the state of the track on it (``appliance/evaluation/late.py``).

Options: ``--seeds N`` (3) from ``--first-seed S`` (0), ``--scenarios a,b`` (names of either
world), ``--keep DIR`` (recordings and runs kept in ``DIR/<world>/recordings`` and
``DIR/<world>/runs``; kept recordings are reused while the generator that made them is
unchanged (``DIR/<world>/generated.json``, ``benchmarks/_kept.py``), and kept runs too when
the code and configuration are the same), ``--jobs N`` (Ray workers and generator processes;
the machine is shared, default 1), ``--config FILE`` (passed to every replay), ``--markdown
FILE`` (the tables as a Markdown page, each with the command that reproduces it),
``--ks-world PATH``, ``--ks-python PATH`` (default: this interpreter when it has the world's
packages, else a venv created under ``~/.cache/collision-warning``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from appliance.batch import engine, report
from appliance.batch.task import Job, JobResult
from appliance.code_digest import code_digest
from appliance.config import load_config
from appliance.errors import ApplianceError
from appliance.evaluation.report import late_of_run, print_table, table_row
from appliance.evaluation import pooled
from benchmarks import _kept
from benchmarks import _kitti_street as ks

CLI = [sys.executable, "-m", "appliance"]
OWN, KITTI = "own", "kitti-street"
PROG = "python -m benchmarks warning_quality"


@dataclass
class World:
    """One world's selection, where its files go, and what came out."""

    name: str
    scenarios: list[str]
    root: Path
    recordings: dict[str, tuple[str, int]] = field(default_factory=dict)  # name -> (scen, seed)
    results: list[dict[str, Any]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    @property
    def dir(self) -> Path:
        return self.root / self.name

    @property
    def rec_dir(self) -> Path:
        return self.dir / "recordings"

    def drop_stale(self, digest: str) -> None:
        """Remove kept recordings another generator made (``_kept.py``), so they are made anew."""
        stale = _kept.drop_stale(self.dir, self.recordings, digest)
        if stale:
            print(f"{self.name}: {len(stale)} kept recordings come from another generator "
                  f"(or none is named): made again", flush=True)

    @property
    def run_dir(self) -> Path:
        return self.root / self.name / "runs"


def own_scenarios() -> list[str]:
    out = subprocess.run([*CLI, "simulate", "--list"], capture_output=True, text=True,
                         check=False)
    if out.returncode != 0:
        raise SystemExit(f"simulate --list failed: {out.stderr.strip() or out.stdout.strip()}")
    return [line.split()[0].rstrip(":") for line in out.stdout.splitlines()
            if line.strip() and not line.startswith((" ", "#"))]


def simulate_own(world: World, seeds: range, jobs: int) -> None:
    """``collision-warning simulate`` for every wanted recording not kept yet (or kept from
    another simulator)."""
    world.rec_dir.mkdir(parents=True, exist_ok=True)
    world.recordings = {f"{name}-seed{seed}": (name, seed)
                        for name in world.scenarios for seed in seeds}
    digest = _kept.own_generator()
    world.drop_stale(digest)
    todo = []
    for rec, (name, seed) in world.recordings.items():
        if not (world.rec_dir / rec / "truth.json").exists():
            todo.append((name, seed, world.rec_dir / rec))

    def one(job: tuple[str, int, Path]) -> str | None:
        name, seed, rec = job
        p = subprocess.run([*CLI, "simulate", name, "--out", str(rec), "--seed", str(seed)],
                           capture_output=True, text=True, check=False)
        if p.returncode == 0:
            return None
        return f"{rec.name}: simulate exit {p.returncode}: " + (
            p.stderr.strip().splitlines() or ["(no message)"])[-1]

    if todo:
        print(f"own: simulating {len(todo)} recordings", flush=True)
    with ThreadPoolExecutor(max_workers=max(jobs, 1)) as pool:
        world.errors += [e for e in pool.map(one, todo) if e]
    _kept.record(world.dir, world.recordings, digest)


def generate_kitti(world: World, seeds: range, jobs: int, python: str, ks_world: Path) -> None:
    world.rec_dir.mkdir(parents=True, exist_ok=True)
    wanted = [(n, s) for n in world.scenarios for s in seeds]
    world.recordings = {ks.recording_name(n, s): (n, s) for n, s in wanted}
    digest = _kept.kitti_generator(ks_world, [ks.STANDING])
    world.drop_stale(digest)
    world.errors += ks.generate(python, ks_world, world.rec_dir, wanted, jobs)
    _kept.record(world.dir, world.recordings, digest)


def replay_all(worlds: list[World], config: str | None, jobs: int) -> dict[str, JobResult]:
    """Every recording of every world in one batch; own-world runs evaluated in the task."""
    cfg = load_config(config)
    batch = [Job(recording=str(w.rec_dir / rec), out_dir=str(w.run_dir / rec),
                 evaluate=w.name == OWN)
             for w in worlds for rec in w.recordings if (w.rec_dir / rec / "truth.json").exists()]
    from tqdm import tqdm

    bar = tqdm(total=len(batch), unit="rec", file=sys.stderr, disable=None, desc="replay")

    def seen(r: JobResult) -> None:
        bar.update(1)
        tqdm.write(f"  {Path(r.out_dir).parent.parent.name}/{r.name}: {r.status}"
                   + (f" ({r.error})" if r.error else f" in {r.replay_s or 0:.1f} s"))

    t0 = time.perf_counter()
    try:
        info = engine.connect(engine.Cluster(workers=max(jobs, 1)))
    except engine.RayMissing:
        print(f"Ray is not installed ({engine.INSTALL_HINT}): replaying one after another",
              flush=True)
        results = engine.run_in_process(batch, cfg, seen)
    else:
        print(f"replaying {len(batch)} recordings on Ray {info.version} with {jobs} workers "
              f"(start-up {info.startup_s:.1f} s)", flush=True)
        try:
            results = engine.run_on_ray(batch, cfg, engine.Cluster(workers=max(jobs, 1)), seen)
        finally:
            engine.disconnect()
    bar.close()
    print(f"replayed in {time.perf_counter() - t0:.0f} s", flush=True)
    for w in worlds:
        c = report.costs([r for r in results if Path(r.out_dir).parent == w.run_dir])
        if c["recordings_replayed"]:
            peak = max(c["peak_rss_mb_per_worker"].values(), default=0.0)
            read = c["read_bytes_total"] or 0
            print(f"  {w.name}: {c['recordings_replayed']} replayed, CPU {c['cpu_ms_per_frame']}"
                  f" ms/frame (replay and evaluation), {read / max(c['frames_replayed'], 1) / 1e3:.0f}"
                  f" kB read/frame, worker peak RSS {peak:.0f} MB")
    return {r.out_dir: r for r in results}


def collect(world: World, runs: dict[str, JobResult], python: str | None,
            ks_world: Path | None) -> None:
    """The world's results, in the shape of ``appliance.evaluation.report``'s, one per recording."""
    scores: dict[str, Any] = {}
    if world.name == KITTI:
        assert python is not None and ks_world is not None
        replayed = [world.rec_dir / rec for rec in world.recordings
                    if str(world.run_dir / rec) in runs
                    and runs[str(world.run_dir / rec)].status != "failed"]
        if replayed:
            try:
                scores = ks.score(python, ks_world, replayed, world.run_dir)
            except ks.WorldError as exc:
                world.errors.append(str(exc))
    for rec, (scenario, seed) in world.recordings.items():
        r = runs.get(str(world.run_dir / rec))
        if r is None:
            res: dict[str, Any] = {"scenario": scenario, "error": "no recording"}
        elif r.status == "failed":
            res = {"scenario": scenario, "error": r.error}
        elif world.name == OWN:
            res = dict(r.evaluation) if r.evaluation else {"scenario": scenario,
                                                           "error": "not evaluated"}
        elif rec in scores:
            res = ks.as_evaluation(scores[rec], ks.duration_s(world.rec_dir / rec))
            try:
                res["late_reasons"] = late_of_run(world.rec_dir / rec, world.run_dir / rec)
            except ApplianceError as exc:    # scored all the same; the breakdown is extra
                world.errors.append(f"{rec}: {exc}")
        else:
            res = {"scenario": scenario, "error": "not scored"}
        res["seed"] = seed
        res["world"] = world.name
        world.results.append(res)


def print_world(world: World) -> list[dict[str, str]]:
    ok = [r for r in world.results if "error" not in r]
    print(f"\n== {world.name}: per run")
    rows = []
    for r in ok:
        row = table_row(r)
        row["scenario"] = f"{r['scenario']}#{r['seed']}"
        rows.append(row)
    print_table(rows)
    for r in world.results:
        if "error" in r:
            print(f"  {r['scenario']}#{r['seed']}: {r['error']}")
    for e in world.errors:
        print(f"  ! {e}")
    print(f"\n== {world.name}: aggregate over seeds")
    agg = pooled.aggregate(world.results)
    print("\n".join(pooled.format_rows(agg)))
    print()
    print("\n".join(pooled.totals_lines(pooled.totals(world.results))))
    return agg


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog=PROG)
    ap.add_argument("--world", choices=(OWN, KITTI, "both"), default="both")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=0, metavar="S",
                    help="seeds S..S+N-1 (held-out seeds: a first seed past the tuned ones)")
    ap.add_argument("--scenarios", help="comma-separated subset (default: all of each world)")
    ap.add_argument("--keep", metavar="DIR", help="keep recordings and runs in DIR")
    ap.add_argument("--jobs", type=int, default=1, help="Ray workers and generator processes")
    ap.add_argument("--config", help="configuration file passed to replay")
    ap.add_argument("--markdown", metavar="FILE", help="also write the tables as Markdown")
    ap.add_argument("--ks-world", metavar="PATH", help="the kitti-street world "
                    "(default: ../shared/worlds/kitti-street beside the repository)")
    ap.add_argument("--ks-python", metavar="PATH", help="interpreter for the kitti-street world")
    args = ap.parse_args(argv)
    if args.config:
        try:
            load_config(args.config)
        except ApplianceError as exc:
            print(f"{PROG}: {exc}", file=sys.stderr)
            return 2
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    wanted = set(args.scenarios.split(",")) if args.scenarios else None
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="warning_quality-"))
    worlds: list[World] = []
    python = ks_world = None
    if args.world in (OWN, "both"):
        names = [n for n in own_scenarios() if wanted is None or n in wanted]
        if names or wanted is None:
            worlds.append(World(OWN, names, work))
    if args.world in (KITTI, "both"):
        ks_world = Path(args.ks_world).resolve() if args.ks_world else ks.default_world()
        try:
            ks.check_world(ks_world)
            python, how = ks.find_python(args.ks_python)
            names = [n for n in ks.scenarios(python, ks_world) if wanted is None or n in wanted]
        except ks.WorldError as exc:
            if args.world == KITTI:
                print(f"{PROG}: kitti-street: {exc}", file=sys.stderr)
                return 2
            print(f"kitti-street skipped: {exc}", flush=True)
        else:
            print(f"kitti-street: {ks_world}, interpreter {python} ({how})", flush=True)
            if names or wanted is None:
                worlds.append(World(KITTI, names, work))
    unknown = (wanted or set()) - {n for w in worlds for n in w.scenarios}
    if unknown or not worlds:
        print(f"{PROG}: unknown scenario(s) for the selected worlds: "
              f"{', '.join(sorted(unknown)) or '-'}", file=sys.stderr)
        return 2
    print(", ".join(f"{w.name}: {len(w.scenarios)} scenarios" for w in worlds)
          + f" x seeds {seeds.start}-{seeds.stop - 1}; work dir {work}", flush=True)
    t0 = time.perf_counter()
    try:
        for w in worlds:
            if w.name == OWN:
                simulate_own(w, seeds, args.jobs)
            else:
                assert python is not None and ks_world is not None
                generate_kitti(w, seeds, args.jobs, python, ks_world)
        t_rec = time.perf_counter() - t0
        runs = replay_all(worlds, args.config, args.jobs)
        for w in worlds:
            collect(w, runs, python, ks_world)
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    tables = {w.name: print_world(w) for w in worlds}
    everything = [r for w in worlds for r in w.results]
    by_world = pooled.aggregate(everything, group=lambda r: str(r["world"]), label="world")
    if len(worlds) > 1:
        by_world.append(pooled.pooled_row(everything, "all", label="world"))
    print("\n== pooled per world")
    print("\n".join(pooled.format_rows(by_world)))
    print(f"\n{time.perf_counter() - t0:.0f} s ({t_rec:.0f} s making recordings)")
    if args.markdown:
        from benchmarks._results_page import write_page

        write_page(Path(args.markdown), args, worlds, tables, by_world, code_digest())
        print(f"wrote {args.markdown}")
    return 0 if all(a["targets"] == "ok" for t in tables.values() for a in t) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
