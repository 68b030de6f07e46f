"""``collision-warning simulate SCENARIO --out DIR [--seed N] [--duration S] [--video mkv|avi|png]``
and ``simulate --list``."""

from __future__ import annotations

import argparse
import sys

from appliance.errors import UsageError
from appliance.sim.scenarios import SCENARIOS


def list_scenarios() -> str:
    width = max(len(n) for n in SCENARIOS)
    return "\n".join(f"{name:<{width}}  {s.description}" for name, s in SCENARIOS.items())


def main(args: argparse.Namespace) -> int:
    if args.list:
        print(list_scenarios())
        return 0
    if not args.scenario:
        raise UsageError("missing SCENARIO (see simulate --list)")
    if args.scenario not in SCENARIOS:
        raise UsageError(f"unknown scenario {args.scenario!r} (see simulate --list)")
    if not args.out:
        raise UsageError("missing --out RECORDING (the directory to create)")
    from appliance.recording import Recording
    from appliance.sim.drive import simulate

    cfg = getattr(args, "cfg", None)
    out = simulate(
        args.scenario,
        args.out,
        seed=args.seed,
        duration=args.duration,
        video=args.video,
        cfg=cfg,
        progress=sys.stderr.isatty(),
    )
    rec = Recording(out)
    truth = rec.truth() or {}
    t = rec.frame_times
    coll = truth.get("collision_t")
    print(
        f"wrote {out}: {args.scenario}, seed {args.seed}, {rec.n_frames} frames "
        f"({rec.meta.camera.width}x{rec.meta.camera.height}, {args.video}), "
        f"t {t[0]:.3f}-{t[-1]:.3f} s "
        f"({t[-1] - t[0]:.2f} s)"
    )
    cam, mount, sim = rec.meta.camera, rec.meta.mount, rec.meta.extra.get("simulator", {})
    print(
        f"look: fx {cam.fx:.0f} px, camera {mount.z_m:.2f} m high pitched "
        f"{mount.pitch_rad:.3f} rad down, {'colour' if sim.get('colour') else 'gray'}, "
        f"texture contrast {sim.get('texture_contrast', 1.0):.2f}"
        f"{', plain movers' if sim.get('plain_movers') else ''}, "
        f"noise {sim.get('noise_sigma', 0.0):.1f} DN"
    )
    if coll is None:
        print("collision_t: none (no collision)")
    else:
        print(
            f"collision_t: {coll:.3f} s (object {truth.get('collision_object')}; "
            f"the last frame is at {t[-1]:.3f} s)"
        )
    return 0
