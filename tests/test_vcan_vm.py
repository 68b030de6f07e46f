"""Host side of the vcan suite: boot the throwaway guest once and run every vcan test in it.

Skips with one line where the machine cannot run the guest (no QEMU, no kernel
image, not root). The other tests here check that the runner fails with one
line, and kills the guest, when something goes wrong.
"""

from __future__ import annotations

import os
import re
import shlex
from pathlib import Path

import pytest
from vcan_vm import VmFailure, VmUnavailable, run_in_vm, suite_command
from vcan_vm.__main__ import EXIT_SKIP, main
from vcan_vm.guest import Kernel, pack_initramfs, resolve_modules, stage_initramfs
from test_vcan_e2e import PREPARED_ENV, prepare_drive
from vcan_vm.runner import boot, check_host, guest_env, job_script

REPO = Path(__file__).resolve().parents[1]
SUITE_LIMIT_S = 600.0


def vm_kernel() -> Kernel:
    """The kernel to boot; skips (one folded line under -ra) where the guest cannot run."""
    if os.environ.get("VCAN_VM") == "1":
        pytest.skip("already inside the vcan VM")
    try:
        return check_host()
    except VmUnavailable as exc:
        pytest.skip(f"vcan VM unavailable: {exc}")


def _one_line(message: str) -> str:
    assert "\n" not in message, message
    return message


def _qemu_children() -> list[str]:
    """Command names of this process's live children that are QEMU."""
    names = []
    for task in Path("/proc/self/task").iterdir():
        for pid in (task / "children").read_text().split():
            comm = Path(f"/proc/{pid}/comm")
            if comm.exists() and comm.read_text().startswith("qemu"):
                names.append(pid)
    return names


def test_vcan_suite_runs_in_the_vm(tmp_path: Path) -> None:
    kernel = vm_kernel()
    # the end-to-end test's drive and plain replay are made here, on the fast host; the slow
    # emulated guest only runs the real-time part (it finds them through PREPARED_ENV)
    prepare_drive(tmp_path, in_vm=True)
    try:
        result = run_in_vm(suite_command(REPO), REPO, timeout_s=SUITE_LIMIT_S,
                           kernel_image=kernel.image, env={PREPARED_ENV: str(tmp_path)})
    except VmFailure as exc:
        pytest.fail(f"vcan VM: {exc}", pytrace=False)
    tail = "\n".join(result.output.splitlines()[-30:])
    print(f"vcan VM: kernel {result.kernel}, boot to test start {result.boot_s:.1f} s, "
          f"suite {result.job_s:.1f} s, total {result.total_s:.1f} s")
    assert result.status == 0, f"in-guest pytest exited {result.status}:\n{tail}"
    collected = re.search(r"collected (\d+) items?(?: / (\d+) deselected)?(?: / (\d+) selected)?",
                          result.output)
    passed = re.search(r"(\d+) passed", result.output)
    assert collected and passed, tail
    n_collected, n_deselected, n_selected = (int(g or 0) for g in collected.groups())
    selected = n_selected or n_collected - n_deselected
    # every selected test ran and passed: a skip inside the VM would hide a missing feature
    assert int(passed.group(1)) == selected > 0, tail
    assert not re.search(r"\d+ (skipped|failed|error)", result.output), tail


def test_missing_module_fails_naming_it() -> None:
    kernel = vm_kernel()
    with pytest.raises(VmFailure) as err:
        resolve_modules(kernel, ("vcan", "no_such_can_module"))
    assert "no_such_can_module" in _one_line(str(err.value))
    assert kernel.version in str(err.value)


def test_module_order_puts_dependencies_first() -> None:
    kernel = vm_kernel()
    names = [m.name for m in resolve_modules(kernel, ("9p", "can-raw", "vcan"))]
    assert len(names) == len(set(names))
    assert names.index("9pnet") < names.index("9p")
    assert names.index("can") < names.index("can-raw")
    assert names[-1] == "vcan"


def test_boot_hang_is_killed_at_the_limit() -> None:
    kernel = vm_kernel()
    with pytest.raises(VmFailure) as err:
        run_in_vm(["true"], REPO, boot_timeout_s=0.5, kernel_image=kernel.image,
                  keep_on_failure=False)
    message = _one_line(str(err.value))
    assert "hung during boot" in message and "QEMU killed" in message
    assert _qemu_children() == []


def test_hung_job_is_killed_at_the_limit() -> None:
    kernel = vm_kernel()
    with pytest.raises(VmFailure) as err:
        run_in_vm(["sh", "-c", "echo about to hang; exec sleep 600"], REPO, timeout_s=15.0,
                  kernel_image=kernel.image, keep_on_failure=False)
    message = _one_line(str(err.value))
    assert "job still running after 15 s" in message
    assert "last output: about to hang" in message
    assert _qemu_children() == []


def _job(tmp_path: Path, kernel: Kernel) -> Path:
    stage_initramfs(kernel, tmp_path / "initramfs")
    (tmp_path / "job.sh").write_text(job_script(["true"], REPO, tmp_path, guest_env()))
    return tmp_path


def test_module_that_fails_to_load_is_named(tmp_path: Path) -> None:
    kernel = vm_kernel()
    job = _job(tmp_path, kernel)
    (vcan_ko,) = (job / "initramfs" / "lib" / "vcan-vm").glob("*-vcan.ko")
    vcan_ko.write_bytes(b"\x7fELF not really a module")
    pack_initramfs(job / "initramfs", job / "initrd.cpio")
    with pytest.raises(VmFailure) as err:
        boot(kernel, job, boot_timeout_s=120.0)
    assert "module vcan failed to load" in _one_line(str(err.value))


def test_kernel_panic_is_a_boot_failure(tmp_path: Path) -> None:
    kernel = vm_kernel()
    job = _job(tmp_path, kernel)
    (job / "initrd.cpio").write_bytes(b"this is not an initramfs\n" * 100)
    with pytest.raises(VmFailure) as err:
        boot(kernel, job, boot_timeout_s=120.0)
    message = _one_line(str(err.value))
    assert "boot failure" in message and "panic" in message.lower()


def test_cli_skips_with_one_line_and_status_77(capsys: pytest.CaptureFixture[str],
                                               tmp_path: Path) -> None:
    status = main(["--kernel", str(tmp_path / "vmlinuz-none"), "--", "true"])
    err = capsys.readouterr().err
    assert status == EXIT_SKIP
    assert err.startswith("vcan-vm: skipped: ") and err.count("\n") == 1


def test_job_script_quotes_arguments(tmp_path: Path) -> None:
    script = job_script(["echo", "a b", "$HOME", "it's"], tmp_path, tmp_path, {"X": "1 2"})
    assert shlex.join(["echo", "a b", "$HOME", "it's"]) in script
    assert "'X=1 2'" in script
