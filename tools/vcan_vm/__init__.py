"""A throwaway QEMU guest with real SocketCAN (vcan0, vcan1) for the vcan integration tests.

The host kernel here has no CAN; Debian's kernel in a small guest does. The
guest chroots into the host's root filesystem (9p), so the project's venv runs
unchanged. ``python -m tools.vcan_vm`` runs the ``vcan``-marked tests in it.
"""

from tools.vcan_vm.guest import VmFailure, VmUnavailable
from tools.vcan_vm.runner import VmResult, run_in_vm

__all__ = ["VmFailure", "VmResult", "VmUnavailable", "run_in_vm"]
