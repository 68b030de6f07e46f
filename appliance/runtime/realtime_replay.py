"""A recording played live: through the drivers, ring buffers and threads, in real time.

Used by ``replay --realtime`` and by the demo. The recording's frames go through
the camera interface (:class:`~appliance.runtime.sources.RecordingSource`), its
CAN frames onto a python-can bus where the real vehicle CAN reader receives them,
its PTU positions through the PTU driver (against the PTU simulator on a
pseudo-terminal) or a PTU player; warnings go out through the real HMI writer.
"""

from __future__ import annotations

import itertools
import os
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from appliance.config import Config
from appliance.errors import RuntimeFailure
from appliance.recording import PtuTrack, Recording
from appliance.runtime.outputs import RunOutputs
from appliance.runtime.recorder import LiveRecorder
from appliance.runtime.sd_notify import SdNotifier
from appliance.runtime.sources import (
    CanPlayer,
    PlaybackClock,
    PtuCommander,
    PtuPlayer,
    RecordingSource,
)
from appliance.runtime.supervisor import FRAME_RING, LiveInputs, RunStats, Supervisor, run_summary
from appliance.runtime.wiring import hmi_writer, ptu_driver, vehicle_reader
from drivers.ptu import PtuDriver, PtuSample
from drivers.ptu_sim import PtuSimulator

START_LEAD_S = 0.3  # s, drivers open before the first recorded sample is played
PTU_ARRIVED_RAD = 2e-3  # rad (about 2 steps of a PTU-D46), the simulator is at the start position
PTU_START_TIMEOUT_S = 5.0  # s, to turn the PTU simulator to the recording's start position
_channels = itertools.count()


@dataclass(frozen=True)
class LiveRig:
    """What a live playback is made of, handed to ``on_start`` (fault injection, monitoring)."""

    supervisor: Supervisor
    camera: RecordingSource
    can_player: CanPlayer | None
    ptu_simulator: PtuSimulator | None
    ptu: PtuDriver | None
    clock: PlaybackClock


@dataclass(frozen=True)
class Buses:
    """Where the replayed vehicle CAN and the HMI output go (python-can interface, channel)."""

    vehicle: tuple[str, str]
    hmi: tuple[str, str]

    @staticmethod
    def private_virtual() -> Buses:
        """Two in-process virtual buses no other run shares."""
        n = f"{os.getpid()}-{next(_channels)}"
        return Buses(("virtual", f"cw-vehicle-{n}"), ("virtual", f"cw-hmi-{n}"))

    @staticmethod
    def from_config(cfg: Config) -> Buses:
        return Buses(
            (cfg.vehicle_can.interface, cfg.vehicle_can.channel),
            (cfg.hmi_can.interface, cfg.hmi_can.channel),
        )


def ptu_at_start(
    cfg: Config, port: str, sink: Callable[[PtuSample], None], track: PtuTrack | None
) -> PtuDriver:
    """The PTU driver on ``port``, its unit turned to where the recording's PTU starts.

    Raises :class:`RuntimeFailure` when the unit does not report that position in time.
    """
    start = (0.0, 0.0) if track is None else (float(track.pan[0]), float(track.tilt[0]))
    arrived = threading.Event()

    def watch(sample: PtuSample) -> None:
        sink(sample)
        if max(abs(sample.pan_rad - start[0]), abs(sample.tilt_rad - start[1])) < PTU_ARRIVED_RAD:
            arrived.set()

    ptu = ptu_driver(cfg, port, watch).start()
    ptu.move_to(*start)
    if not arrived.wait(PTU_START_TIMEOUT_S):
        ptu.stop(timeout=0.5)
        raise RuntimeFailure(
            f"PTU on {port} did not reach the recording's start position "
            f"(pan {start[0]:.4f}, tilt {start[1]:.4f} rad) within {PTU_START_TIMEOUT_S:.0f} s"
        )
    return ptu


def play_live(
    rec: Recording,
    cfg: Config,
    out_dir: str | Path,
    buses: Buses,
    *,
    ptu_simulator: bool = False,
    play_can: bool = True,
    on_event: Callable[[str], None] | None = None,
    notifier: SdNotifier | None = None,
    on_start: Callable[[LiveRig], None] | None = None,
    recorder: LiveRecorder | None = None,
) -> tuple[RunStats, dict[str, Any]]:
    """Play ``rec`` live; returns the run's statistics and its ``summary.json`` content.

    With ``recorder`` the run also records what the drivers delivered (``run --record``).
    """
    out = Path(out_dir)
    outputs = RunOutputs(out, can_log=False)
    sup = Supervisor(cfg, outputs, notifier=notifier, on_event=on_event, recorder=recorder)

    first = float(rec.frame_times[0])
    first_can = next(iter(rec.can_messages()), None)
    t0_rec = min(first, first_can.timestamp) if first_can is not None else first
    track = rec.ptu()
    # a slowed playback (runtime.replay_rate < 1) stretches the drivers' staleness limits alike
    rate = cfg.runtime.replay_rate
    vehicle = hmi = ptu = sim = player_bus = None
    players: list[Any] = []
    # the simulator's pty under a stable name, as the udev rule gives the real PTU: a re-plugged
    # simulator gets a new pty, which the driver finds again by that name
    link_dir = tempfile.TemporaryDirectory(prefix="cw-ptu-") if ptu_simulator else None
    try:
        vehicle = vehicle_reader(
            cfg,
            sup.can_ring.put,
            recorder.add_can if recorder is not None else None,
            bus=buses.vehicle,
            stale_scale=1.0 / rate,
        ).start()
        if play_can and not vehicle.wait_stats(lambda s: s.opens >= 1, 5.0):
            raise RuntimeFailure(
                f"vehicle CAN {buses.vehicle[0]}:{buses.vehicle[1]} did not open: "
                f"{vehicle.stats.last_error}"
            )
        hmi = hmi_writer(cfg, out / "can_out.log", bus=buses.hmi).start()
        if link_dir is not None:
            sim = PtuSimulator(Path(link_dir.name) / "ptu").start()
            ptu = ptu_at_start(cfg, sim.port, sup.add_ptu, track)
        clock = PlaybackClock(t0_rec, time.monotonic() + START_LEAD_S, rate)
        if recorder is not None:
            recorder.to_recording = clock.recording
        can_player = None
        if play_can:
            player_bus = can.Bus(interface=buses.vehicle[0], channel=buses.vehicle[1])
            can_player = CanPlayer(rec.can_messages(), player_bus, clock)
            players.append(can_player.start())
        if track is not None:
            if ptu is not None:  # the simulator turns as the recording's PTU did
                players.append(PtuCommander(track, ptu, clock).start())
            else:
                players.append(PtuPlayer(track, sup.add_ptu, clock).start())
        if sim is not None:
            players.append(sim)
        camera = RecordingSource(
            rec, clock, capacity=FRAME_RING, stale_s=cfg.camera.stale_s / rate
        )
        inputs = LiveInputs(
            camera=camera,
            vehicle=vehicle,
            ptu=ptu,
            hmi=hmi,
            players=players,
            to_recording=clock.recording,
            ptu_enabled=ptu_simulator or track is not None,
            finished=camera.finished,
        )
        if on_start is not None:
            on_start(LiveRig(sup, camera, can_player, sim, ptu, clock))
        try:
            stats = sup.run(inputs)
        finally:
            vehicle = hmi = ptu = None  # the supervisor stopped them and the players
            players = []
        if camera.error is not None:
            raise camera.error
    finally:
        for part in (vehicle, hmi, ptu):
            if part is not None:
                part.stop(timeout=0.5)
        for pl in players:
            pl.stop()
        if sim is not None:
            sim.stop()  # (a second stop does nothing)
        if link_dir is not None:
            link_dir.cleanup()
        if player_bus is not None:
            player_bus.shutdown()
    summary = run_summary(
        stats, cfg, {"warnings_issued": sum(1 for w in stats.warnings if w.level > 0)}
    )
    outputs.write_summary(summary)
    outputs.close()
    return stats, summary


def replay_realtime(
    rec: Recording, cfg: Config, out_dir: Path, buses: Buses | None = None
) -> RunStats:
    """``replay --realtime``: private virtual buses unless the configuration names real ones."""
    stats, summary = play_live(
        rec,
        cfg,
        out_dir,
        buses or Buses.private_virtual(),
        on_event=lambda line: print(line, flush=True),
    )
    print(
        f"replayed {stats.frames_processed} of {stats.frames_read} frames of {rec.path} "
        f"in real time -> {out_dir}"
    )
    return stats
