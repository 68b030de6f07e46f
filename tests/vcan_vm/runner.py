"""Boot the throwaway QEMU guest, run one command inside it, hand back output and status.

The guest runs Debian's kernel with SocketCAN (``vcan0`` = vehicle bus, ``vcan1`` =
HMI bus) and works chrooted into the host's root filesystem, shared read-write
over 9p, so the command (for example the project's venv Python running pytest)
runs unchanged. Output and exit status come back as files in a job directory on
the shared filesystem; the serial console is only watched for progress markers
(``vcan-vm: stage ...`` / ``vcan-vm: error: ...``) to time the boot and to name
what went wrong. A time limit kills the guest, so a hung guest never hangs the
caller.
"""

from __future__ import annotations

import os
import queue
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from .guest import Kernel, VmFailure, VmUnavailable, build_initramfs, find_kernel

QEMU = "qemu-system-x86_64"
TCG_CPU = "max,-avx2"  # see qemu_command
MARKER = re.compile(r"vcan-vm: (stage|error:) ?(.*)")
# Environment variables handed from the caller to the command in the guest.
PASSED_ENV = ("PATH", "HOME", "LANG", "LC_ALL", "PYTHONPATH", "VIRTUAL_ENV", "PYTHONHASHSEED",
              "PYTEST_ADDOPTS")


@dataclass(frozen=True)
class VmResult:
    """What the command in the guest did.

    :ivar status: the command's exit status.
    :ivar output: its stdout and stderr, interleaved.
    :ivar kernel: the guest kernel's version.
    :ivar boot_s: s, QEMU start to the command's start (host monotonic clock).
    :ivar job_s: s, the command's start to the guest's power-off.
    """

    status: int
    output: str
    kernel: str
    boot_s: float
    job_s: float

    @property
    def total_s(self) -> float:
        return self.boot_s + self.job_s


@dataclass(frozen=True)
class _Event:
    kind: str  # "stage", "error" or "eof"
    text: str
    t: float   # host monotonic time it was seen


def check_host(kernel_image: Path | None = None) -> Kernel:
    """The kernel to boot, once this machine is known to be able to run the guest.

    :raises VmUnavailable: not root, no QEMU, no kernel image with modules.
    """
    if os.geteuid() != 0:
        raise VmUnavailable("not root (the guest shares / over 9p with passthrough permissions)")
    if shutil.which(QEMU) is None:
        raise VmUnavailable(f"{QEMU} not found (apt-get install qemu-system-x86)")
    return find_kernel(kernel_image)


def suite_command(repo: Path) -> list[str]:
    """The in-guest suite: every ``vcan``-marked test under ``repo/tests``, in one pytest.

    Only the files that use the marker are collected (named ``test_vcan_*.py``
    or mentioning ``mark.vcan``), so an unrelated test module cannot break or
    slow the VM run; ``-v`` prints each test's name as it starts, so a hang
    names its test.
    """
    files = sorted(str(p.relative_to(repo)) for p in (repo / "tests").glob("test_*.py")
                   if p.name.startswith("test_vcan_") or "mark.vcan" in p.read_text(errors="replace"))
    return [sys.executable, "-m", "pytest", "-v", "-m", "vcan", "-p",
            "no:cacheprovider", *files]


def job_script(command: Sequence[str], cwd: Path, job: Path, env: Mapping[str, str]) -> str:
    """The shell script the guest runs chrooted into the host root (``/bin/sh``)."""
    exports = " ".join(shlex.quote(f"{k}={v}") for k, v in sorted(env.items()))
    q = shlex.quote
    return "\n".join([
        "#!/bin/sh",
        "# written by tests.vcan_vm for one guest run",
        (f"cd {q(str(cwd))} || {{ echo {q(f'vcan-vm: error: working directory {cwd} not found')}; "
         "exit 1; }"),
        "echo 'vcan-vm: stage job-start'",
        (f"{{ env -i {exports} {shlex.join(command)} < /dev/null; "
         f"echo $? > {q(str(job / 'status.tmp'))}; }} 2>&1 | tee {q(str(job / 'output'))}"),
        f"mv {q(str(job / 'status.tmp'))} {q(str(job / 'status'))}",
        "sync",
        "",
    ])


def guest_env(extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """The command's environment in the guest: a few of the caller's variables plus markers."""
    env = {k: os.environ[k] for k in PASSED_ENV if k in os.environ}
    path = [p for p in env.get("PATH", "").split(":") if p]
    # the tests run ip(8) and can-utils: make sure the system directories are searched
    path += [p for p in ("/usr/local/sbin", "/usr/local/bin", "/usr/sbin", "/usr/bin", "/sbin",
                         "/bin") if p not in path]
    env["PATH"] = ":".join(path)
    env.update({"VCAN_VM": "1", "PYTHONUNBUFFERED": "1", "TMPDIR": "/dev/shm", "TERM": "dumb"})
    env.update(extra or {})
    return env


def qemu_command(kernel: Kernel, initrd: Path, job: Path, memory_mb: int, accel: str,
                 cpus: int) -> list[str]:
    """QEMU with no devices but a serial console and the host root over virtio-9p.

    TCG's CPU hides AVX2: under QEMU 7.2's AVX2 emulation numpy's AVX2 ``argpartition``
    segfaulted in the pipeline (MSAC sampling); without it every library takes its SSE4 path.
    """
    return [QEMU, "-accel", accel, "-cpu", TCG_CPU if accel == "tcg" else "host",
            "-m", str(memory_mb), "-smp", str(cpus),
            "-nodefaults", "-display", "none", "-serial", "stdio", "-no-reboot",
            "-kernel", str(kernel.image), "-initrd", str(initrd),
            "-virtfs", ("local,path=/,mount_tag=hostroot,security_model=passthrough,"
                        "id=hostroot,multidevs=remap"),
            "-append", f"console=ttyS0 quiet panic=-1 vcanvm.job={job}"]


class _Console:
    """What the console watcher saw: the last lines and the kernel's panic line, if any."""

    def __init__(self) -> None:
        self.tail: deque[str] = deque(maxlen=20)
        self.panic: str | None = None

    def add(self, line: str) -> None:
        line = line.strip()
        if line:
            self.tail.append(line)
        if self.panic is None and "Kernel panic" in line:
            self.panic = line[line.index("Kernel panic"):]

    def last(self) -> str:
        return self.panic or (self.tail[-1] if self.tail else "(none)")


def _watch_console(stream: IO[bytes], log: IO[bytes], events: queue.Queue[_Event],
                   seen: _Console, echo: IO[str] | None) -> None:
    """Copy the serial console to ``log`` (and ``echo``), reporting markers and the end."""
    for raw in iter(stream.readline, b""):
        log.write(raw)
        log.flush()
        line = raw.decode(errors="replace").rstrip("\r\n")
        if echo is not None:
            echo.write(line + "\n")
            echo.flush()
        seen.add(line)
        m = MARKER.search(line)
        if m:
            kind = "stage" if m.group(1) == "stage" else "error"
            events.put(_Event(kind, m.group(2).strip(), time.monotonic()))
    events.put(_Event("eof", "", time.monotonic()))


def _last_line(path: Path) -> str:
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return "(no output)"
    return lines[-1] if lines else "(no output)"


def run_in_vm(command: Sequence[str], cwd: Path, *, timeout_s: float = 600.0,
              boot_timeout_s: float = 120.0, kernel_image: Path | None = None,
              memory_mb: int = 1024, accel: str = "tcg", cpus: int = 1,
              env: Mapping[str, str] | None = None, keep: bool = False,
              keep_on_failure: bool = True, console: IO[str] | None = None) -> VmResult:
    """Run ``command`` in ``cwd`` inside a fresh guest with ``vcan0`` and ``vcan1`` up.

    :param command: argv, run with ``env -i`` and :func:`guest_env` plus ``env``.
    :param cwd: working directory (a host path; the guest sees the same path).
    :param timeout_s: s, from QEMU start; the guest is killed when it runs out.
    :param boot_timeout_s: s, from QEMU start to the command's start.
    :param keep: keep the whole job directory (initramfs, console log, output) after the run.
    :param keep_on_failure: after a failure keep the console log and output (the message
        names the directory); False removes everything.
    :param console: stream the serial console (boot messages and output) here live.
    :raises VmUnavailable: this machine cannot run the guest (skip).
    :raises VmFailure: missing module, boot failure, hang or lost result (one line).
    """
    kernel = check_host(kernel_image)
    job = Path(tempfile.mkdtemp(prefix="vcan-vm-"))
    try:
        if re.search(r"\s", str(job)):
            raise VmUnavailable(f"temporary directory {job} contains white space")
        build_initramfs(kernel, job / "initramfs", job / "initrd.cpio")
        (job / "job.sh").write_text(job_script(command, cwd, job, guest_env(env)))
        result = boot(kernel, job, memory_mb, accel, cpus, timeout_s, boot_timeout_s, console)
    except VmFailure as exc:
        if not keep_on_failure:
            shutil.rmtree(job, ignore_errors=True)
            raise
        if not keep:  # the logs tell what happened; the 6 MB initramfs does not
            shutil.rmtree(job / "initramfs", ignore_errors=True)
            (job / "initrd.cpio").unlink(missing_ok=True)
        raise VmFailure(f"{exc} (console log and output in {job})") from None
    except BaseException:
        shutil.rmtree(job, ignore_errors=True)
        raise
    if not keep:
        shutil.rmtree(job, ignore_errors=True)
    return result


def boot(kernel: Kernel, job: Path, memory_mb: int = 1024, accel: str = "tcg", cpus: int = 1,
         timeout_s: float = 600.0, boot_timeout_s: float = 120.0,
         console: IO[str] | None = None) -> VmResult:
    """Boot ``job/initrd.cpio`` with ``kernel``; the guest runs ``job/job.sh``.

    Leaves ``console.log``, ``qemu.err``, ``output`` and ``status`` in ``job``.
    :raises VmFailure: see :func:`run_in_vm`.
    """
    events: queue.Queue[_Event] = queue.Queue()
    seen = _Console()
    argv = qemu_command(kernel, job / "initrd.cpio", job, memory_mb, accel, cpus)
    t0 = time.monotonic()
    with (job / "console.log").open("wb") as log, (job / "qemu.err").open("wb") as err:
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=err)
        assert proc.stdout is not None
        watcher = threading.Thread(target=_watch_console, name="vcan-vm-console", daemon=True,
                                   args=(proc.stdout, log, events, seen, console))
        watcher.start()
        started: float | None = None
        try:
            while True:
                deadline = t0 + (boot_timeout_s if started is None else timeout_s)
                try:
                    event = events.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    if started is None:
                        raise VmFailure(f"guest hung during boot: no job start after "
                                        f"{boot_timeout_s:.0f} s, QEMU killed; console: "
                                        f"{seen.last()}") from None
                    # the job's output file lives on a cached 9p mount: what the guest had not
                    # written back when it was killed is only on the console, which tee also feeds
                    last = _last_line(job / "output")
                    if last == "(no output)":
                        last = seen.last()
                    raise VmFailure(f"guest hung: job still running after {timeout_s:.0f} s, "
                                    f"QEMU killed; last output: {last}") from None
                if event.kind == "eof":
                    break
                if started is None and event.kind == "error":
                    raise VmFailure(f"guest failed: {event.text}")
                if started is None and event.text == "job-start":
                    started = event.t
            proc.wait(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            watcher.join(timeout=10)
    t_end = time.monotonic()
    status_file = job / "status"
    if started is None:
        qemu_err = _last_line(job / "qemu.err") if proc.returncode != 0 else ""
        why = (f"QEMU exited with status {proc.returncode}: {qemu_err}" if qemu_err
               else f"console: {seen.last()}")
        raise VmFailure(f"guest stopped before the job started (boot failure); {why}")
    if not status_file.is_file():
        raise VmFailure("guest stopped without the job's exit status (guest crashed?); "
                        f"last output: {_last_line(job / 'output')}")
    try:
        status = int(status_file.read_text().strip())
    except ValueError:
        raise VmFailure(f"unreadable exit status in {status_file}") from None
    return VmResult(status=status,
                    output=(job / "output").read_text(errors="replace"),
                    kernel=kernel.version, boot_s=started - t0, job_s=t_end - started)
