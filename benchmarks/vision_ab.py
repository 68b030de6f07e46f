"""``python -m benchmarks vision_ab``: the cost of a vision setting or change, measured side by side.

``perceive`` runs twice over the same recordings, A and B alternating frame by frame (the
order flips every frame) so that both see the same machine load; p(x) is fed back through
the spatio-temporal filter for each, as in the pipeline. Prints the median ms per frame of
each and the ratio B / A.

* Settings: in one process, the defaults (A) against changed settings (B: ``--config=FILE``
  and/or ``--set=section.key=value``, repeatable). Without any change it is an A/A run: the
  ratio then shows the noise floor of the comparison. Example: the cost of 300 particles
  instead of 500, ``--set=detection.particles=300``.
* Code: ``--against=DIR`` runs A with the checkout at DIR (its ``.venv/bin/python`` if it has
  one) and B with this one, each in a worker process (``_perceive_worker.py``) with its own
  defaults, and also counts the frames whose outputs agree bit for bit. ``--against=.`` is the
  A/A run.

Options: ``--recordings=DIR``, ``--scenarios=a,b`` (default: four scenarios of the vision
benchmark's cache, simulated when missing), ``--frames=N`` (per recording, default 150),
``--duration=S``, ``--seed=N``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import cv2

from appliance.config import Config, load_config
from appliance.messages import ProbabilityMap
from appliance.vision import perception as P
from benchmarks.vision import next_probability_map, open_case, recordings, sensor_frames

SCENARIOS = ("car_crossing_intersection,cyclist_crossing_intersection,"
             "pedestrian_crossing_nearside,bend_static")


def overrides(sets: list[str]) -> dict[str, dict[str, Any]]:
    """``section.key=value`` strings (value in TOML syntax) -> nested overrides."""
    out: dict[str, dict[str, Any]] = {}
    for item in sets:
        key, sep, value = item.partition("=")
        section, dot, name = key.partition(".")
        if not sep or not dot:
            raise SystemExit(f"--set {item!r}: expected section.key=value")
        try:
            out.setdefault(section, {})[name] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out.setdefault(section, {})[name] = value   # a bare word: a string
    return out


def side_by_side(cases: list[Any], b_of: Any, frames: int) -> dict[str, list[float]]:
    ms: dict[str, list[float]] = {"A": [], "B": []}
    for case in cases:
        cfgs: dict[str, Config] = {"A": case.cfg, "B": b_of(case.cfg)}
        state = {k: P.init_vision_state(c, case.camera, 0) for k, c in cfgs.items()}
        pmap: dict[str, ProbabilityMap | None] = {"A": None, "B": None}
        for i, (frame, sensors) in enumerate(sensor_frames(case, frames)):
            for k in ("A", "B") if i % 2 == 0 else ("B", "A"):
                t0 = time.perf_counter()
                state[k], ego, particles = P.perceive(state[k], frame, sensors, pmap[k], cfgs[k],
                                                      case.camera)
                if i > 0:    # the first frame has no flow
                    ms[k].append((time.perf_counter() - t0) * 1e3)
                pmap[k] = next_probability_map(pmap[k], particles, ego, case.camera, cfgs[k])
    return ms


def checkout_python(checkout: Path) -> str:
    """The interpreter of a checkout: its ``.venv``'s, else this one."""
    venv = checkout / ".venv" / "bin" / "python"
    return str(venv) if venv.exists() else sys.executable


def against_checkout(checkout: Path, paths: list[Path], frames: int
                     ) -> tuple[dict[str, list[float]], int, int]:
    """perceive of ``checkout`` (A) and of this checkout (B) over ``paths``, interleaved frame by
    frame in two worker processes. Returns the ms per frame of each (the first frame of each
    recording has no flow and is left out), the frames whose outputs agree and all frames."""
    worker = Path(__file__).with_name("_perceive_worker.py")
    sides = {"A": checkout.resolve(), "B": Path(__file__).resolve().parent.parent}
    # the worker's source runs with -c: run as a file, its directory (this benchmarks/, whose
    # drivers.py would hide the drivers package) would come first on the module path
    source = worker.read_text()
    procs = {k: subprocess.Popen([checkout_python(d), "-c", source, str(frames), *map(str, paths)],
                                 cwd=d, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                 env={**os.environ, "PYTHONPATH": str(d)})
             for k, d in sides.items()}
    ms: dict[str, list[float]] = {"A": [], "B": []}
    agree = total = 0
    try:
        counts = set()
        for k, p in procs.items():
            assert p.stdout is not None
            ready = p.stdout.readline().split()
            if ready[:1] != ["ready"]:
                raise SystemExit(f"--against: the worker of {sides[k]} did not start")
            counts.add(int(ready[1]))
        if len(counts) != 1:
            raise SystemExit(f"--against: the two checkouts read different frames ({counts})")
        total = counts.pop()
        for i in range(total):
            digests = []
            for k in ("A", "B") if i % 2 == 0 else ("B", "A"):
                p = procs[k]
                assert p.stdin is not None and p.stdout is not None
                p.stdin.write("next\n")
                p.stdin.flush()
                index, t, digest = p.stdout.readline().split()
                if int(index) > 0:   # the first frame has no flow
                    ms[k].append(float(t))
                digests.append(digest)
            agree += digests[0] == digests[1]
    finally:
        for p in procs.values():
            if p.stdin is not None:
                p.stdin.close()
            p.wait()
    return ms, agree, total


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks vision_ab")
    ap.add_argument("--recordings", help="directory of recordings (default: simulate)")
    ap.add_argument("--scenarios", default=SCENARIOS)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--duration", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--config", help="B: a configuration file over the defaults")
    ap.add_argument("--set", action="append", default=[], help="B: section.key=value")
    ap.add_argument("--against", help="A: the checkout at this directory (B: this one)")
    args = ap.parse_args(argv)
    if args.against and (args.config or args.set):
        ap.error("--against compares code: each side runs with its own defaults, "
                 "without --config or --set")
    cv2.setNumThreads(1)
    base = load_config()
    b_file = load_config(args.config) if args.config else None
    changes = overrides(args.set)
    wanted = set(args.scenarios.split(","))
    paths = [p for p in recordings(args, base) if not args.recordings or p.name in wanted]
    if not paths:
        raise SystemExit(f"no recordings of {args.scenarios} in {args.recordings}")
    if args.against:
        ms, agree, total = against_checkout(Path(args.against), paths, args.frames)
        a, b = statistics.median(ms["A"]), statistics.median(ms["B"])
        print(f"perceive, median ms per frame over {len(ms['A'])} frames each, cv2 threads 1, "
              f"A and B interleaved in two processes; outputs identical in {agree}/{total} frames:")
        print(f"  A {Path(args.against).resolve()} {a:8.2f}")
        print(f"  B {Path(__file__).resolve().parent.parent} {b:8.2f}")
        print(f"  ratio B / A {b / a:.3f}")
        return 0
    cases = [open_case(p, base) for p in paths]

    def b_of(cfg: Config) -> Config:
        out = cfg
        if b_file is not None:   # the file's sections over this recording's configuration
            out = out.with_overrides({s: vars(getattr(b_file, s)) for s in ("flow", "detection",
                                      "refinement", "probability_map")})
        return out.with_overrides(changes) if changes else out

    ms = side_by_side(cases, b_of, args.frames)
    a, b = statistics.median(ms["A"]), statistics.median(ms["B"])
    label = " ".join([*(["--config " + args.config] if args.config else []), *args.set]) or "A/A"
    print(f"perceive, median ms per frame over {len(ms['A'])} frames each, cv2 threads 1, "
          f"A and B interleaved:")
    print(f"  A defaults {a:8.2f}")
    print(f"  B {label} {b:8.2f}")
    print(f"  ratio B / A {b / a:.3f}")
    return 0
