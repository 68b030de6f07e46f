"""Shared fixtures: the default configuration and small synthetic recordings."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest

from appliance.config import Config, load_config
from appliance.recording import RecordingWriter, meta_from_config


@pytest.fixture(scope="session")
def default_config() -> Config:
    return load_config()


def write_small_recording(
    path: Path, cfg: Config, n_frames: int = 5, video: str = "mkv", seed: int = 0
) -> dict[str, object]:
    """A tiny recording with random frames, 50 Hz CAN and 20 Hz PTU; returns what was written."""
    rng = np.random.default_rng(seed)
    meta = meta_from_config(cfg)
    frames, times, msgs, ptu = [], [], [], []
    with RecordingWriter(path, meta, video=video) as w:
        for i in range(n_frames):
            img = (rng.random((cfg.camera.height, cfg.camera.width)) * 255).astype(np.uint8)
            t = 100.0 + i / 30.0
            w.write_frame(img, t)
            frames.append(img)
            times.append(t)
        for k in range(int(n_frames / 30.0 * 50) + 2):
            m = can.Message(
                timestamp=100.0 + k * 0.02,
                arbitration_id=0x1A0,
                is_extended_id=False,
                data=bytes([k & 0xFF, 0x10, 0, 0]),
                channel="can0",
            )
            w.write_can(m)
            msgs.append(m)
        for k in range(4):
            w.write_ptu(100.0 + k * 0.05, 0.01 * k, -0.002 * k)
            ptu.append((100.0 + k * 0.05, 0.01 * k, -0.002 * k))
    return {"frames": frames, "times": times, "can": msgs, "ptu": ptu}
