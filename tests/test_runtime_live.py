"""The live runtime: real drivers, ring buffers and threads on a recording played in real time.

Fault injection (camera outage, vehicle CAN silence, PTU garbage and unplug) must give the right
status bits, recover without a restart and lose nothing from the logs; SIGTERM stops within 2 s;
a run recorded with --record replays to the same warnings.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from appliance.config import Config
from appliance.recording import PtuTrack, Recording, apply_meta
from appliance.replay import replay
from appliance.runtime.realtime_replay import Buses, LiveRig, play_live, ptu_at_start
from appliance.runtime.recorder import LiveRecorder
from appliance.runtime.sources import PlaybackClock, PtuCommander
from appliance.sim.drive import simulate
from drivers.ptu import PtuSample
from drivers.ptu_sim import PtuSimulator

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def static_drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate("bend_static", tmp_path_factory.mktemp("sim") / "bend", seed=3, duration=4.5)


def _rows(path: Path) -> list[dict[str, object]]:
    return [json.loads(x) for x in path.read_text().splitlines() if x]


class StatusLog:
    """The run's event lines (``on_event``), with a wait on the latest ApplianceStatus change."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._cond = threading.Condition()

    def __call__(self, line: str) -> None:
        with self._cond:
            self.lines.append(line)
            self._cond.notify_all()

    def _faults(self) -> set[str] | None:
        """The latest status's faults; None before the first frame was processed."""
        status = [line for line in self.lines if line.startswith("status ")]
        if not status or status[-1].startswith("status starting"):
            return None
        named = status[-1].partition("(faults: ")[2].partition(")")[0]
        return set() if named == "none" else set(named.split(", "))

    def wait(self, holds: Callable[[set[str]], bool], timeout: float = 30.0) -> bool:
        """Until a frame was processed and the latest status's faults satisfy ``holds``."""
        def reached() -> bool:
            faults = self._faults()
            return faults is not None and holds(faults)

        with self._cond:
            return self._cond.wait_for(reached, timeout)


def test_faults_are_flagged_and_recovered(
    static_drive: Path, tmp_path: Path, default_config: Config
) -> None:
    """Each fault is injected once the status names none of them and lasts until the status
    shows it; the run ends when the last one has cleared. Every wait is on a status change,
    none on the clock, so a loaded machine only makes it slower (where it starves the CAN
    threads, vehicle CAN may also go stale by itself: the next fault then waits until it has
    cleared). Played at half speed (the staleness limits stretched alike) for room to do all of
    it within the drive."""
    rec = Recording(static_drive, defaults=default_config)
    cfg = apply_meta(default_config.with_overrides({"runtime": {"replay_rate": 0.5}}), rec.meta)
    log = StatusLog()
    steps: list[str] = []
    script: list[threading.Thread] = []

    def inject(rig: LiveRig) -> None:
        can_player, sim = rig.can_player, rig.ptu_simulator
        assert can_player is not None and sim is not None
        faults = (
            ("camera", rig.camera.interrupt, rig.camera.resume),
            ("vehicle_can_stale", can_player.mute, can_player.unmute),
            ("ptu", sim.disconnect, sim.reconnect),
        )

        injected = {name for name, _, _ in faults}

        def run() -> None:
            try:
                for name, start, stop in faults:
                    if not log.wait(lambda f: not f & injected):
                        return
                    start()
                    if not log.wait(lambda f, n=name: n in f):
                        return
                    steps.append(f"{name} flagged")
                    stop()
                    if not log.wait(lambda f, n=name: n not in f):
                        return
                    steps.append(f"{name} cleared")
            finally:
                rig.supervisor.stop_event.set()  # done (or stuck): end the run

        script.append(threading.Thread(target=run, name="fault-script", daemon=True))
        script[0].start()

    stats, summary = play_live(
        rec, cfg, tmp_path / "run", Buses.private_virtual(), ptu_simulator=True,
        on_event=log, on_start=inject,
    )
    script[0].join(5.0)
    assert steps == [f"{f} {what}" for f in ("camera", "vehicle_can_stale", "ptu")
                     for what in ("flagged", "cleared")], (steps, log.lines)
    changes = stats.status_changes
    assert any("fault" in c and "camera" in c for c in changes), changes  # camera: state fault
    # nothing lost from the logs: one tracks row and one egomotion row per processed frame
    tracks = _rows(tmp_path / "run" / "tracks.jsonl")
    assert len(tracks) == stats.frames_processed == summary["frames_processed"]
    ego = (tmp_path / "run" / "egomotion.csv").read_text().splitlines()
    assert len(ego) == stats.frames_processed + 1
    # summary.json counts the frames the HMI writer sent, as can_out.log holds them
    sent = (tmp_path / "run" / "can_out.log").read_text().splitlines()
    assert summary["can_frames_sent"] == summary["hmi_can"]["sent"] == len(sent) > 0


def test_demo_run_recorded_replays_to_the_same_warnings(
    tmp_path: Path, default_config: Config
) -> None:
    # the car is warned about well before the impact (the pedestrian only late, behind a parked car)
    src = simulate("car_crossing_intersection", tmp_path / "sim", seed=1, duration=6.0)
    rec = Recording(src, defaults=default_config)
    # at half speed, so that a loaded test machine still processes (nearly) every frame live
    cfg = apply_meta(default_config.with_overrides({"runtime": {"replay_rate": 0.5}}), rec.meta)
    recorder = LiveRecorder(tmp_path / "recorded", cfg).start()
    stats, _ = play_live(rec, cfg, tmp_path / "live", Buses.private_virtual(), recorder=recorder)
    recorder.stop()
    assert recorder.stats.recordings == 1 and recorder.stats.dropped == 0
    recorded = Recording(recorder.paths[0], defaults=default_config)
    assert recorded.n_frames == stats.frames_read
    assert len(list(recorded.can_messages())) == len(list(rec.can_messages()))
    first = next(recorded.frames())
    assert (first.image == next(rec.frames(start=first.index)).image).all()  # lossless
    replay(recorded, apply_meta(default_config, recorded.meta), tmp_path / "replayed")
    live = _rows(tmp_path / "live" / "warnings.jsonl")
    again = _rows(tmp_path / "replayed" / "warnings.jsonl")
    # The live run may skip frames when processing falls behind (counted as overrun), and its
    # sensor samples arrive with live jitter, so the two runs are not identical frame for frame.
    # What must agree: both reach level 2, and they are at level 2 during largely the same part
    # of the drive. The recording keeps the drive's clock (the playback was at half speed).
    assert max((w["level"] for w in live), default=0) == 2, live
    assert max((w["level"] for w in again), default=0) == 2, again
    assert abs(recorded.frame_times[0] - rec.frame_times[0]) < 1e-6
    assert abs(recorded.frame_times[-1] - rec.frame_times[-1]) < 0.05  # not stretched
    end = float(rec.frame_times[-1])
    live_l2 = _level2_intervals(live, end)
    again_l2 = _level2_intervals(again, end)
    overlap = sum(max(0.0, min(a1, b1) - max(a0, b0)) for a0, a1 in live_l2 for b0, b1 in again_l2)
    shorter = min(sum(b - a for a, b in live_l2), sum(b - a for a, b in again_l2))
    assert overlap >= 0.5 * shorter, (live_l2, again_l2)


def _level2_intervals(rows: list[dict[str, object]], end: float) -> list[tuple[float, float]]:
    """[start, end) of every stretch at level 2."""
    out, start = [], None
    for w in rows:
        t = float(w["t"])  # type: ignore[arg-type]
        if w["level"] == 2 and start is None:
            start = t
        elif w["level"] != 2 and start is not None:
            out.append((start, t))
            start = None
    if start is not None:
        out.append((start, end))
    return out


def test_run_without_its_devices_says_so_every_10_s_and_stops_on_sigterm(tmp_path: Path) -> None:
    """No camera, no PTU, a SocketCAN vehicle bus that cannot open: one line each when it
    happens, with the likely cause for the CAN bus, then "still waiting" every 10 s; SIGTERM
    stops it within 2 s."""
    cfg = tmp_path / "live.toml"
    cfg.write_text(
        f'[camera]\ndevice = "{tmp_path}/no-camera"\n[ptu]\nport = "{tmp_path}/no-ptu"\n'
        '[vehicle_can]\ninterface = "socketcan"\nchannel = "cw-no-such-can"\n'
        '[hmi_can]\ninterface = "virtual"\nchannel = "cw-sigterm-hmi"\n'
        f'[runtime]\nout_dir = "{tmp_path}/out"\n'
    )
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "appliance", "run", "--config", str(cfg)],
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert proc.stderr is not None
    seen: list[str] = []
    deadline = time.monotonic() + 60.0
    try:
        # until every missing device was reported again (the first time after 10 s)
        while time.monotonic() < deadline:
            if all(any(line.startswith(f"INFO {name}: still waiting after 1") for line in seen)
                   for name in ("camera", "PTU", "vehicle CAN")):
                break
            ready, _, _ = select.select([proc.stderr], [], [], 1.0)
            if ready:
                seen.append(proc.stderr.readline().rstrip("\n"))
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=10)
        elapsed = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    rest = proc.stderr.read()
    assert any("running:" in line for line in seen), seen
    can_lines = [line for line in seen if "vehicle CAN" in line]
    assert any("no SocketCAN" in line or "no network interface cw-no-such-can" in line
               for line in can_lines), can_lines
    for name in ("camera", "PTU", "vehicle CAN"):
        again = [line for line in seen if line.startswith(f"INFO {name}: still waiting")]
        assert len(again) == 1 and "after 10 s" in again[0], (name, seen)
    assert rc == 0, rest
    assert elapsed < 2.0, elapsed
    assert "Traceback" not in rest
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["frames_processed"] == 0
    # the ApplianceStatus heartbeats the HMI writer sent meanwhile, counted as can_out.log has them
    sent = (tmp_path / "out" / "can_out.log").read_text().splitlines()
    assert summary["can_frames_sent"] == len(sent) > 50, (summary, len(sent))


def test_recorder_rotates_by_duration_and_each_piece_replays(
    tmp_path: Path, default_config: Config
) -> None:
    """run --record: a long drive becomes several recordings, each valid on its own."""
    import can as pycan

    from drivers.camera import CameraFrame

    cfg = default_config.with_overrides({"runtime": {"record_rotate_s": 1.0}})
    rec = LiveRecorder(tmp_path / "rec", cfg).start()
    rng = np.random.default_rng(0)
    for i in range(75):  # 2.5 s at 30 frames/s
        t = 100.0 + i / 30.0
        rec.add_can(
            pycan.Message(
                timestamp=t - 0.01,
                arbitration_id=0x1A0,
                is_extended_id=False,
                data=b"\x10\x0e\x00\x00",
            )
        )
        rec.add_ptu(PtuSample(t - 0.005, 0.0, 0.0))
        rec.add_frame(CameraFrame(i, t, rng.integers(0, 255, (480, 640), dtype=np.uint8)))
    rec.stop()
    assert rec.stats.recordings == 3 and rec.stats.frames == 75 and rec.stats.dropped == 0
    frames = 0
    for path in rec.paths:
        r = Recording(path, defaults=default_config)
        r.validate()
        frames += r.n_frames
        assert r.frame_times[-1] - r.frame_times[0] < 1.0
        assert len(list(r.can_messages())) >= r.n_frames - 1
    assert frames == 75


def test_ptu_simulator_turns_as_the_recording_did(default_config: Config) -> None:
    """The demo's PTU simulator starts where the recording's PTU was and follows its pans, so
    the PTU angles the pipeline sees match the ones the simulated frames were rendered with."""
    import numpy as np

    t = 1000.0 + np.arange(0.0, 2.0, 0.05)
    # 0.1 rad, then a 0.35 rad pan right in 1 s (as the intersection scenarios do), then held
    pan = 0.1 - 0.35 * np.clip(t - 1000.5, 0.0, 1.0)
    track = PtuTrack(t=t, pan=pan, tilt=np.zeros_like(t))
    samples: list[PtuSample] = []
    with PtuSimulator() as sim:
        ptu = ptu_at_start(default_config, sim.port, samples.append, track)
        try:
            assert abs(samples[-1].pan_rad - 0.1) < 2e-3  # at the start position before playing
            clock = PlaybackClock(1000.0, time.monotonic() + 0.1)
            commander = PtuCommander(track, ptu, clock).start()
            assert commander.finished.wait(5.0) and commander.error is None
            n = ptu.stats.samples  # a few more polls after the last move
            assert ptu.wait_stats(lambda s: s.samples >= n + 10, 2.0)
        finally:
            ptu.stop(timeout=1.0)
    played = [s for s in samples if clock.recording(s.t) >= 1000.0]
    rec_t = np.array([clock.recording(s.t) for s in played])
    got = np.array([s.pan_rad for s in played])
    want = np.interp(rec_t, t, pan)
    assert np.max(np.abs(got - want)) < 0.05  # within a poll period of the ramp
    assert abs(got[-1] - pan[-1]) < 2e-3  # and exactly where the recording ended
    assert np.min(got) > pan[-1] - 2e-3  # no overshoot
