"""Worker of ``vision_ab --against``: ``perceive`` of one checkout, one frame per request.

Run with ``python -c`` (its source) by the checkout's python in the checkout's directory,
``PYTHONPATH`` set to it, so that ``appliance`` and ``benchmarks`` are that checkout's. Arguments: frames per recording, then
the recordings. Prints ``ready N`` (N frames in all), then, for each line read from stdin,
runs ``perceive`` on the next frame (p(x) fed back as in the pipeline) and prints the frame
index, its ms and a digest of its outputs (particle weights and positions, rotation).
"""

from __future__ import annotations

import hashlib
import sys
import time
from pathlib import Path

import cv2

from appliance.config import load_config
from appliance.vision import perception as P
from benchmarks.vision import next_probability_map, open_case, sensor_frames


def main(argv: list[str]) -> int:
    cv2.setNumThreads(1)
    frames = int(argv[0])
    base = load_config()
    work = []
    for path in argv[1:]:
        case = open_case(Path(path), base)
        work.append((case, list(sensor_frames(case, frames))))
    print("ready", sum(len(items) for _, items in work), flush=True)
    for case, items in work:
        state = P.init_vision_state(case.cfg, case.camera, 0)
        pmap = None
        for frame, sensors in items:
            sys.stdin.readline()
            t0 = time.perf_counter()
            state, ego, particles = P.perceive(state, frame, sensors, pmap, case.cfg, case.camera)
            ms = (time.perf_counter() - t0) * 1e3
            pmap = next_probability_map(pmap, particles, ego, case.camera, case.cfg)
            digest = hashlib.sha256(particles.weights.tobytes() + particles.positions.tobytes()
                                    + ego.rotation.tobytes()).hexdigest()[:16]
            print(frame.index, f"{ms:.4f}", digest, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
