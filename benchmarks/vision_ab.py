"""``python -m benchmarks vision_ab``: the cost of a vision setting, measured side by side.

``perceive`` runs twice over the same recordings in one process, with the defaults (A) and
with changed settings (B: ``--config=FILE`` and/or ``--set=section.key=value``, repeatable),
alternating A and B frame by frame (the order flips every frame) so that both see the same
machine load; p(x) is fed back through the spatio-temporal filter for each, as in the
pipeline. Prints the median ms per frame of each and the ratio B / A. Without any change it
is an A/A run: the ratio then shows the noise floor of the comparison.

Example: the cost of 300 particles instead of 500, ``--set=detection.particles=300``.
Options: ``--recordings=DIR``, ``--scenarios=a,b`` (default: four scenarios of the vision
benchmark's cache, simulated when missing), ``--frames=N`` (per recording, default 150),
``--duration=S``, ``--seed=N``.
"""

from __future__ import annotations

import argparse
import statistics
import time
import tomllib
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


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks vision_ab")
    ap.add_argument("--recordings", help="directory of recordings (default: simulate)")
    ap.add_argument("--scenarios", default=SCENARIOS)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--duration", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--config", help="B: a configuration file over the defaults")
    ap.add_argument("--set", action="append", default=[], help="B: section.key=value")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    base = load_config()
    b_file = load_config(args.config) if args.config else None
    changes = overrides(args.set)
    wanted = set(args.scenarios.split(","))
    paths = [p for p in recordings(args, base) if not args.recordings or p.name in wanted]
    if not paths:
        raise SystemExit(f"no recordings of {args.scenarios} in {args.recordings}")
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
