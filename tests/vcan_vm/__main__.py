"""``python -m tests.vcan_vm [options] [-- COMMAND ...]``: run COMMAND in the vcan guest.

Without a command it runs the in-guest test suite: ``<this python> -m pytest -v
-m vcan tests/test_vcan_*.py`` in the working directory. Prints
the command's output, then one summary line on stderr, and exits with the command's
exit status; 77 (the automake convention for "skipped") with one line when this
machine cannot run the guest; 1 with one line when the guest failed (missing module,
boot failure, hang).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .guest import VmFailure, VmUnavailable
from .runner import run_in_vm, suite_command

EXIT_SKIP = 77


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m tests.vcan_vm", description=__doc__.split("\n")[0])
    p.add_argument("--timeout", type=float, default=600.0, metavar="S",
                   help="kill the guest after S seconds from start (default 600)")
    p.add_argument("--boot-timeout", type=float, default=120.0, metavar="S",
                   help="kill the guest if the command has not started after S seconds "
                        "(default 120)")
    p.add_argument("--kernel", type=Path, metavar="IMAGE",
                   help="kernel image (default: newest /boot/vmlinuz-* with /lib/modules)")
    p.add_argument("--memory", type=int, default=1024, metavar="MB", help="guest RAM (1024)")
    p.add_argument("--cpus", type=int, default=1, help="guest CPUs (default 1)")
    p.add_argument("--accel", choices=("tcg", "kvm"), default="tcg",
                   help="tcg (software, default: KVM hung at boot on this machine) or kvm")
    p.add_argument("--cwd", type=Path, default=Path.cwd(),
                   help="working directory of the command (default: here)")
    p.add_argument("--console", action="store_true",
                   help="stream the guest's serial console live instead of printing the "
                        "output at the end")
    p.add_argument("--keep", action="store_true", help="keep the job directory after success")
    p.add_argument("command", nargs=argparse.REMAINDER,
                   help="command and arguments after -- (default: the vcan test suite)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    command = command or suite_command(args.cwd.resolve())
    try:
        result = run_in_vm(command, args.cwd.resolve(), timeout_s=args.timeout,
                           boot_timeout_s=args.boot_timeout, kernel_image=args.kernel,
                           memory_mb=args.memory, accel=args.accel, cpus=args.cpus,
                           keep=args.keep, console=sys.stdout if args.console else None)
    except VmUnavailable as exc:
        print(f"vcan-vm: skipped: {exc}", file=sys.stderr)
        return EXIT_SKIP
    except VmFailure as exc:
        print(f"vcan-vm: error: {exc}", file=sys.stderr)
        return 1
    if not args.console:
        sys.stdout.write(result.output)
        sys.stdout.flush()
    print(f"vcan-vm: kernel {result.kernel}, boot to job start {result.boot_s:.1f} s, "
          f"job {result.job_s:.1f} s, total {result.total_s:.1f} s, exit status {result.status}",
          file=sys.stderr)
    return result.status


if __name__ == "__main__":
    raise SystemExit(main())
