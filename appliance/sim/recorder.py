"""Writes a simulated drive as a drive recording (spec: "Drive recording") with ``truth.json``."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from appliance.recording import RecordingWriter
from appliance.sim import sensors
from appliance.sim.drive import SimStep, SimulatedDrive


def write_recording(
    drive: SimulatedDrive,
    out_dir: str | Path,
    video: str = "mkv",
    progress: bool = False,
    steps: Iterable[SimStep] | None = None,
) -> Path:
    """Stream ``drive`` (or the given ``steps`` of it) into a new recording directory.

    ``truth.json`` is written last: a killed simulator leaves a recording the reader rejects
    (frame count) and without truth.
    """
    out = Path(out_dir)
    objects: dict[int, dict[str, Any]] = {
        o["id"]: dict(o, frames={}) for o in drive.truth_header["objects"]
    }
    poses: dict[str, Any] = {}
    it: Iterable[SimStep] = drive if steps is None else steps
    if progress:
        from tqdm import tqdm

        it = tqdm(it, total=drive.n_frames, unit="frame", desc=drive.name, leave=False)
    with RecordingWriter(out, drive.meta, video=video, fps=sensors.FPS) as w:
        for step in it:
            w.write_frame(step.image, step.t)
            for msg in step.can_messages:
                w.write_can(msg)
            for t, pan, tilt in step.ptu_samples:
                w.write_ptu(t, pan, tilt)
            poses[str(step.index)] = step.truth_frame["camera_pose"]
            for oid, rec in step.truth_frame["objects"].items():
                objects[int(oid)]["frames"][str(step.index)] = rec
        truth = {
            k: drive.truth_header[k]
            for k in ("scenario", "collision", "collision_t", "collision_object")
        }
        truth["seed"] = drive.seed
        truth["objects"] = [o for o in objects.values() if o["frames"] or o["moving"]]
        truth["camera_poses"] = poses
        w.write_truth(truth)
    return out
