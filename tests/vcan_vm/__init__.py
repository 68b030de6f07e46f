"""A throwaway QEMU guest with real SocketCAN (vcan0, vcan1) for the vcan integration tests.

The host kernel here has no CAN; Debian's kernel in a small guest does. The
guest chroots into the host's root filesystem (9p), so the project's venv runs
unchanged. ``python -m tests.vcan_vm`` runs the ``vcan``-marked tests in it.
"""

from .guest import VmFailure, VmUnavailable
from .runner import VmResult, run_in_vm, suite_command

__all__ = ["VmFailure", "VmResult", "VmUnavailable", "run_in_vm", "suite_command"]
