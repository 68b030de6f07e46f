"""Command line: ``collision-warning run | replay | batch | simulate | demo | evaluate | ptu-sim |
import-video``.

Exit status 0 on success, 2 on bad arguments, configuration or input (one line
naming the file, key or line), 1 on a runtime failure. No traceback unless
``--debug`` is given.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

from appliance import __version__
from appliance.errors import ApplianceError
from appliance.evaluation.columns import legend

PROG = "collision-warning"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


# subcommand -> module whose ``main(args) -> int`` runs it
COMMANDS = {
    "run": "appliance.live",
    "replay": "appliance.replay",
    "batch": "appliance.batch.cli",
    "simulate": "appliance.sim.cli",
    "demo": "appliance.demo",
    "evaluate": "appliance.evaluation.report",
    "ptu-sim": "drivers.ptu_sim",
    "import-video": "appliance.import_video",
}


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Monocular collision warning appliance.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    p.add_argument("--debug", action="store_true", help="print tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser(
        "run", help="live: V4L2 camera, serial PTU, SocketCAN (the systemd service)"
    )
    run.add_argument("--config", required=True, help="TOML file overriding config/default.toml")
    run.add_argument(
        "--record", metavar="DIR", help="also write every input as drive recordings under DIR"
    )
    run.add_argument("--out", metavar="DIR", help="output directory (default: runtime.out_dir)")

    rp = sub.add_parser("replay", help="run the pipeline on a drive recording")
    rp.add_argument("recording", help="drive recording directory")
    rp.add_argument(
        "--out", required=True, metavar="DIR", help="output directory (new or empty)"
    )
    rp.add_argument(
        "--force",
        action="store_true",
        help="--out holds an earlier run: remove its files (outputs, evaluation, videos) first",
    )
    rp.add_argument("--config", help="TOML file overriding config/default.toml")
    rp.add_argument(
        "--realtime",
        action="store_true",
        help="feed the drivers' recording sources at the recorded pace, as live",
    )
    rp.add_argument("--video", metavar="FILE", help="also write an annotated video")
    rp.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")

    bt = sub.add_parser(
        "batch",
        help="replay (and evaluate) many recordings on Ray: local, or a cluster by address",
    )
    bt.add_argument(
        "recordings",
        nargs="+",
        metavar="RECORDING",
        help="drive recordings; a directory of recordings stands for all of them",
    )
    bt.add_argument(
        "--out", required=True, metavar="DIR", help="output directory: DIR/<recording name>/"
    )
    bt.add_argument("--config", help="TOML file overriding config/default.toml")
    bt.add_argument(
        "--evaluate", action="store_true", help="also score every recording that has truth.json"
    )
    bt.add_argument(
        "--address",
        metavar="ADDR",
        help="join the Ray cluster at ADDR (auto, ray://HOST:PORT) instead of a local Ray",
    )
    bt.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local Ray CPUs (default: all of this machine's); on a cluster, at most N "
        "recordings at once (default: one per CPU of the cluster)",
    )

    sim = sub.add_parser("simulate", help="write a synthetic drive recording with truth.json")
    sim.add_argument("scenario", nargs="?", help="scenario name (see --list)")
    sim.add_argument("--out", metavar="RECORDING", help="recording directory to create")
    sim.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    sim.add_argument(
        "--duration", type=float, metavar="S", help="override the scenario duration, s"
    )
    sim.add_argument(
        "--video",
        choices=("mkv", "avi", "png"),
        default="mkv",
        help="frame storage (default mkv, FFV1 lossless)",
    )
    sim.add_argument("--list", action="store_true", help="list the scenarios and exit")

    demo = sub.add_parser(
        "demo", help="simulated drives through the real drivers, live (the main job)"
    )
    demo.add_argument(
        "--out", metavar="DIR", default="out/demo", help="output directory (default out/demo)"
    )
    demo.add_argument("--config", help="TOML file overriding config/default.toml")

    ev = sub.add_parser(
        "evaluate",
        help="score a run against the recording's truth.json",
        description="Score a run against the recording's truth.json: prints a table, writes\n"
        "evaluation.json and timeline.png into RUN_DIR. A run that did not finish (no\n"
        "summary.json) is refused.",
        epilog="columns of the table:\n" + legend(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ev.add_argument("recording", help="simulated drive recording (with truth.json)")
    ev.add_argument("run_dir", help="output directory of a replay or run")

    iv = sub.add_parser(
        "import-video",
        help="make a drive recording of your own video (a dashcam's), for replay",
        description="Make a drive recording of a video file: the camera from --fx, --hfov or "
        "--calibration, the mount from --height and --pitch, the car's speed (and yaw rate) "
        "from --speed or --speed-csv as CAN frames of the configured vehicle DBC.",
    )
    iv.add_argument("video", help="video file (anything OpenCV reads)")
    iv.add_argument("--out", required=True, metavar="REC", help="recording directory to create")
    cam = iv.add_mutually_exclusive_group(required=True)
    cam.add_argument("--fx", type=float, metavar="PX", help="focal length in pixels of the video")
    cam.add_argument("--hfov", type=float, metavar="DEG", help="horizontal field of view, deg")
    cam.add_argument(
        "--calibration",
        metavar="FILE",
        help="OpenCV YAML/XML/JSON with camera_matrix, distortion_coefficients "
        "(image_width, image_height)",
    )
    iv.add_argument(
        "--height", type=float, required=True, metavar="M", help="camera height above the road, m"
    )
    iv.add_argument(
        "--pitch",
        type=float,
        required=True,
        metavar="DEG",
        help="camera pitch, deg, positive looks down (0: optical axis level)",
    )
    speed = iv.add_mutually_exclusive_group(required=True)
    speed.add_argument(
        "--speed", type=float, metavar="M/S", help="constant speed straight ahead, m/s"
    )
    speed.add_argument(
        "--speed-csv",
        metavar="FILE",
        help="CSV t,speed_m_s[,yaw_rate_rad_s], t in s from the start of the video",
    )
    iv.add_argument(
        "--frames",
        type=_frame_range,
        metavar="FIRST:LAST",
        help="import only these frames of the video (inclusive; either may be left out)",
    )
    iv.add_argument(
        "--config",
        metavar="FILE",
        help="TOML file overriding config/default.toml ([vehicle_can] DBC, [mount], "
        "[camera] width)",
    )
    iv.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")

    ptu = sub.add_parser("ptu-sim", help="simulated pan-tilt unit on a pseudo-terminal")
    ptu.add_argument("--latency", type=float, default=0.0, metavar="S", help="reply latency, s")
    ptu.add_argument(
        "--garbage",
        type=float,
        default=0.0,
        metavar="P",
        help="probability of garbage bytes before a reply",
    )
    ptu.add_argument("--link", metavar="PATH", help="also create a symlink to the pty at PATH")
    return p


def _frame_range(text: str) -> tuple[int, int | None]:
    from appliance.import_video import parse_frames

    return parse_frames(text)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if hasattr(args, "config"):
            from appliance.config import load_config

            args.cfg = load_config(args.config)
        module = importlib.import_module(COMMANDS[args.command])
        return int(module.main(args))
    except ApplianceError as exc:
        print(f"{PROG} {args.command}: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # the last line of defence: one line, not a traceback
        if args.debug:
            raise
        print(
            f"{PROG} {args.command}: internal error: {type(exc).__name__}: {exc} "
            "(rerun with --debug for details)",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
