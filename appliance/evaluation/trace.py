"""Where one mover was lost between the particles and the warning: a per-frame trace.

``python -m appliance.evaluation.trace RECORDING [--object ID] [--frames A:B] [--config FILE]
[--json]``

``collision-warning evaluate`` says *that* a mover was confirmed late or warned late; this
says *where* in the chain it happened. It replays the recording (the same pipeline step as
``replay``) and prints, for every frame in which the truth has the object, one row:

* ``truth``: its box (clipped to the image), the visible fraction and ``E`` when the frame
  counts for the detection delay (eligible, :func:`~appliance.evaluation.metrics.eligible_mask`);
* ``p``: the highest p(x) in its box, the map the clusters are cut from at
  ``clustering.threshold`` (below it, no cluster: look at the particles and the likelihood);
* ``clusters``: the clusters overlapping its box, each ``[box] N q`` (correspondences, eq. 20);
  a cluster in fewer than ``tracking.confirm_frames`` frames in a row never becomes a track;
* ``tracks``: the confirmed tracks overlapping its box, each ``#id IoU d= ttc=`` (a track
  counts as a detection from IoU 0.3 on) and, in quotes, its reason: why it warns or what
  keeps it from warning (``tracks.jsonl``); and the warning level.

The default object is the colliding one (``collision_object``, else the first mover). Outputs
of the replay go to a temporary directory. A recording without truth is a usage error.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from appliance.config import load_config
from appliance.decision.decide import DecisionOutput
from appliance.errors import UsageError
from appliance.evaluation.metrics import clip_box, ego_motion, eligible_mask, iou
from appliance.evaluation.runfiles import Box, Truth, TruthObject, parse_truth
from appliance.messages import Frame, StepOutput
from appliance.replay import open_recording, replay

NEAR_PX = 10.0   # a cluster or track this close to the truth box is listed


@dataclass(frozen=True)
class TraceRow:
    """One frame of the trace (see the module docstring); boxes (u0, v0, u1, v1) px."""

    frame: int
    t: float
    truth: Box
    visible: float
    eligible: bool
    p_max: float
    clusters: tuple[tuple[Box, int, float], ...]
    tracks: tuple[tuple[int, Box, float, float | None, float | None, str | None], ...]
    level: int


def _box(b: Any, digits: int = 1) -> Box:
    """A box (4 numbers) as a tuple of floats rounded to ``digits``."""
    u0, v0, u1, v1 = (round(float(x), digits) for x in b)
    return (u0, v0, u1, v1)


def _near(a: Box, b: Box, margin: float) -> bool:
    return (a[0] < b[2] + margin and a[2] > b[0] - margin and a[1] < b[3] + margin
            and a[3] > b[1] - margin)


def trace_row(frame: int, t: float, truth_box: Box, visible: float, eligible: bool,
              out: DecisionOutput, margin: float = NEAR_PX) -> TraceRow:
    """The trace row of one frame from the decision stage's output ``out``."""
    p, scale = out.prob_map.p, out.prob_map.scale
    rows, cols = p.shape
    u0, v0, u1, v1 = truth_box
    r0, r1 = max(int(v0) // scale, 0), min(int(np.ceil(v1 / scale)), rows)
    c0, c1 = max(int(u0) // scale, 0), min(int(np.ceil(u1 / scale)), cols)
    p_max = float(p[r0:r1, c0:c1].max()) if r1 > r0 and c1 > c0 else 0.0
    clusters = tuple((_box(c.bbox), int(c.n), round(float(c.mean_probability), 2))
                     for c in out.clusters if _near(c.bbox, truth_box, margin))
    tracks = tuple((tr.id, _box(tr.bbox), round(iou(tr.bbox, truth_box), 2), tr.distance_m,
                    tr.ttc_s, tr.reason) for tr in out.tracks if _near(tr.bbox, truth_box, margin))
    return TraceRow(frame=frame, t=round(t, 3), truth=_box(truth_box), visible=round(visible, 2),
                    eligible=eligible, p_max=round(p_max, 2), clusters=clusters, tracks=tracks,
                    level=out.warning_level)


def default_object(truth: Truth) -> TruthObject:
    """The colliding object, else the first mover, else the first object."""
    movers = [o for o in truth.objects if o.moving] or list(truth.objects)
    if not movers:
        raise UsageError("truth.json has no objects to trace")
    return next((o for o in movers if o.id == truth.collision_object), movers[0])


def format_row(r: TraceRow) -> str:
    def box(b: Box) -> str:
        return "[" + " ".join(f"{x:.0f}" for x in b) + "]"

    def num(v: float | None, unit: str) -> str:
        return "-" if v is None else f"{v:.2f}{unit}"

    cl = " ".join(f"{box(b)} N{n} q{q:.2f}" for b, n, q in r.clusters) or "-"
    tr = " ".join(f"#{i} {box(b)} IoU{v:.2f} d={num(d, 'm')} ttc={num(s, 's')}"
                  + (f' "{why}"' if why else "")
                  for i, b, v, d, s, why in r.tracks) or "-"
    return (f"{r.frame:5d} {box(r.truth):>18} {r.visible:4.2f} {'E' if r.eligible else ' '} "
            f"p{r.p_max:4.2f} L{r.level} | clusters {cl} | tracks {tr}")


def run_trace(recording: str | Path, object_id: int | None = None,
              frames: tuple[int, int] | None = None, config: str | None = None
              ) -> tuple[TruthObject, int | None, list[TraceRow]]:
    """Replay ``recording`` and trace one object (``object_id``, default :func:`default_object`)
    over ``frames`` (first, last; default all in which the truth has it). Returns the object,
    its first eligible frame (None: never) and the rows."""
    rec, cfg = open_recording(recording, load_config(config))
    raw = rec.truth()
    if raw is None:
        raise UsageError(f"{rec.path}: no truth.json; only simulated recordings can be traced")
    truth = parse_truth(raw, str(rec.path / "truth.json"))
    if object_id is None:
        obj = default_object(truth)
    else:
        found = [o for o in truth.objects if o.id == object_id]
        if not found:
            ids = ", ".join(str(o.id) for o in truth.objects)
            raise UsageError(f"{rec.path / 'truth.json'}: no object {object_id} (objects: {ids})")
        obj = found[0]
    width, height = rec.meta.camera.width, rec.meta.camera.height
    elig = eligible_mask(obj, ego_motion(truth.objects), width, height)
    first, last = frames if frames is not None else (int(obj.frames[0]), int(obj.frames[-1]))
    rows: list[TraceRow] = []

    def on_step(frame: Frame, out: StepOutput, decision: Any) -> None:
        i = obj.at(frame.index)
        if i is None or not first <= frame.index <= last:
            return
        box = clip_box(obj.bbox[i], width, height)
        rows.append(trace_row(frame.index, frame.t, _box(box, 3), float(obj.visible[i]),
                              bool(elig[i]), decision))

    with tempfile.TemporaryDirectory() as tmp:
        replay(rec, cfg, Path(tmp) / "run", on_step=on_step)
    first_eligible = int(obj.frames[elig][0]) if np.any(elig) else None
    return obj, first_eligible, rows


def _frames(text: str) -> tuple[int, int]:
    try:
        a, b = text.split(":")
        return int(a), int(b)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--frames expects FIRST:LAST, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m appliance.evaluation.trace",
                                 description=__doc__.split("\n\n")[0] if __doc__ else None)
    ap.add_argument("recording")
    ap.add_argument("--object", type=int, default=None, help="truth object id (default: the "
                    "colliding object, else the first mover)")
    ap.add_argument("--frames", type=_frames, default=None, metavar="FIRST:LAST")
    ap.add_argument("--config", default=None, help="configuration file (as for replay)")
    ap.add_argument("--json", action="store_true", help="JSON lines instead of the table")
    args = ap.parse_args(argv)
    try:
        obj, first_eligible, rows = run_trace(args.recording, args.object, args.frames,
                                              args.config)
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        for r in rows:
            print(json.dumps(asdict(r)))
        return 0
    print(f"object {obj.id} ({obj.cls}): {len(rows)} frames traced; first eligible frame "
          f"{'-' if first_eligible is None else first_eligible}")
    print("frame       truth box    vis E p(x)  L | clusters [box] N q(eq. 20) | confirmed tracks")
    for r in rows:
        print(format_row(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
