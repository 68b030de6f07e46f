"""The vision benchmark's static false-evidence measure: how long, and where."""

from __future__ import annotations

import numpy as np

from appliance.messages import ParticleSet
from benchmarks.vision import RunLog, longest_false_run

W, H = 640, 480


def _frame(high: list[tuple[float, float]], rng: np.random.Generator) -> ParticleSet:
    """500 particles of weight 0.1 spread over the image, plus ``high`` ones of weight 0.9."""
    low = rng.uniform((0, 0), (W - 1, H - 1), size=(500, 2))
    pos = np.vstack([low, np.array(high, dtype=float).reshape(-1, 2)])
    w = np.concatenate([np.full(len(low), 0.1), np.full(len(high), 0.9)])
    return ParticleSet(positions=pos, flow=np.zeros_like(pos), weights=w,
                       valid=np.ones(len(pos), dtype=bool), window_px=9, flow_std_px=0.5)


def test_the_longest_run_is_measured_where_it_happens() -> None:
    rng = np.random.default_rng(3)
    log = RunLog()
    # frames 10-29 of a recording: a lone high-weight particle near (100, 50) for frames 12-16,
    # drifting 10 px a frame (one region: the cell and its neighbours); a second place, (500,
    # 400), for frames 20-22 and 25-26 (two runs of 3 and 2); nothing otherwise
    for k in range(10, 30):
        high = []
        if 12 <= k <= 16:
            high.append((100.0 + 10.0 * (k - 12), 50.0))
        if 20 <= k <= 22 or 25 <= k <= 26:
            high.append((500.0, 400.0))
        log.particles.append(_frame(high, rng))
        log.frames.append(k)
    run = longest_false_run(log, W, H)
    assert run.frames == 5
    assert (run.first, run.last) == (12, 16)
    # the region that kept it through frame 16 is the cell the particle left from, within a
    # cell of where it was: its centre lies within 48 px of the particle's path
    u, v = run.centre_px
    assert 100.0 - 48.0 <= u <= 140.0 + 48.0 and abs(v - 50.0) <= 48.0
    # a region must hold 3 such particles with min_particles=3: none does
    none = longest_false_run(log, W, H, min_particles=3)
    assert none.frames == 0 and (none.first, none.last) == (-1, -1)


def test_a_static_scene_without_high_weights_has_no_run() -> None:
    rng = np.random.default_rng(4)
    log = RunLog()
    for k in range(8):
        log.particles.append(_frame([], rng))
        log.frames.append(k)
    assert longest_false_run(log, W, H).frames == 0
