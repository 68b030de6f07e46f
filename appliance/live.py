"""``collision-warning run --config FILE [--record DIR]``: live, with the real drivers.

V4L2 camera, serial PTU, SocketCAN vehicle bus and HMI bus, as the configuration
says. A device that is missing at start is reported in one line and retried with
back-off while the appliance runs degraded (under systemd: no crash loop).
SIGTERM or SIGINT stops everything, flushes the logs and exits within 2 s.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import Any

import cv2
import cv2.utils.logging

from appliance.config import Config
from appliance.errors import RuntimeFailure
from appliance.runtime.outputs import RunOutputs
from appliance.runtime.recorder import LiveRecorder
from appliance.runtime.sd_notify import SdNotifier
from appliance.runtime.supervisor import LiveInputs, Supervisor, run_summary
from appliance.runtime.wiring import check_config, hmi_writer, ptu_driver, vehicle_reader
from drivers.camera import create_source

log = logging.getLogger("collision-warning")


def build_inputs(
    cfg: Config, sup: Supervisor, out_dir: Path, recorder: LiveRecorder | None
) -> LiveInputs:
    """Open the real drivers as configured, their sinks pointing at the supervisor's rings."""
    c, p = cfg.camera, cfg.ptu
    camera = create_source(
        "v4l2",
        device=c.device,
        width=c.width,
        height=c.height,
        fps=c.fps,
        pixel_format=c.pixel_format,
        stale_s=c.stale_s,
        timestamps=c.timestamps,
    )
    vehicle = vehicle_reader(
        cfg, sup.can_ring.put, recorder.add_can if recorder is not None else None
    ).start()
    ptu = None
    if p.enabled:
        ptu = ptu_driver(cfg, p.port, sup.add_ptu).start()
    hmi = hmi_writer(cfg, out_dir / "can_out.log").start()
    players: list[Any] = [recorder] if recorder is not None else []
    return LiveInputs(
        camera=camera, vehicle=vehicle, ptu=ptu, hmi=hmi, players=players, ptu_enabled=p.enabled
    )


def install_signal_handlers(stop: threading.Event) -> None:
    def handler(signum: int, frame: FrameType | None) -> None:
        log.info("%s: stopping", signal.Signals(signum).name)
        stop.set()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def main(args: argparse.Namespace) -> int:
    cfg: Config = args.cfg
    logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(levelname)s %(message)s")
    # the drivers log a lost camera once; OpenCV would repeat it on every reopen attempt
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    check_config(cfg)  # before any output is created
    out_dir = Path(args.out or cfg.runtime.out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RuntimeFailure(
            f"{out_dir}: cannot create the output directory: {exc.strerror}"
        ) from None
    record_dir = args.record or (cfg.runtime.record_dir if cfg.runtime.record else None)
    recorder = LiveRecorder(record_dir, cfg).start() if record_dir else None
    sup = Supervisor(
        cfg,
        RunOutputs(out_dir, can_log=False),
        notifier=SdNotifier(),
        on_event=lambda line: log.info("%s", line),
        recorder=recorder,
    )
    install_signal_handlers(sup.stop_event)
    inputs = build_inputs(cfg, sup, out_dir, recorder)
    log.info(
        "running: camera %s, vehicle CAN %s:%s, PTU %s, HMI %s:%s, outputs %s%s",
        cfg.camera.device,
        cfg.vehicle_can.interface,
        cfg.vehicle_can.channel,
        cfg.ptu.port if cfg.ptu.enabled else "disabled",
        cfg.hmi_can.interface,
        cfg.hmi_can.channel,
        out_dir,
        f", recording to {record_dir}" if record_dir else "",
    )
    stats = sup.run(inputs)
    extra: dict[str, Any] = {"warnings_issued": sum(1 for w in stats.warnings if w.level > 0)}
    if recorder is not None:
        extra["recordings"] = [str(p) for p in recorder.paths]
        extra["recorder"] = recorder.stats.__dict__
    sup.outputs.write_summary(run_summary(stats, cfg, extra))
    sup.outputs.close()
    log.info("stopped after %d frames", stats.frames_processed)
    return 0
