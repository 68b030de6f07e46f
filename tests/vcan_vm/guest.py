"""Host-side preparation of the throwaway guest: kernel, modules, initramfs.

Nothing here hard-codes a kernel version: the kernel is the newest
``/boot/vmlinuz-<kver>`` that has a ``/lib/modules/<kver>`` tree, and the module
load order comes from ``modprobe -S <kver> --show-depends``.
"""

from __future__ import annotations

import gzip
import lzma
import os
import re
import shutil
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

# Modules the guest needs, in load order: virtio + 9p to mount the host root,
# then SocketCAN (``can-raw`` must be loaded explicitly or AF_CAN sockets fail).
BOOT_MODULES = ("virtio_pci", "9pnet_virtio", "9p")
CAN_MODULES = ("can", "can-raw", "can-bcm", "vcan")

INIT_TEMPLATE = Path(__file__).with_name("init.sh")


class VmUnavailable(Exception):
    """This machine cannot run the VM at all (no QEMU, no kernel image, not root): skip."""


class VmFailure(Exception):
    """The VM could not run the job (missing module, boot failure, hang): fail, one line."""


@dataclass(frozen=True)
class Kernel:
    """A bootable kernel image and the version string naming its module tree."""

    image: Path
    version: str

    @property
    def modules_dir(self) -> Path:
        return Path("/lib/modules") / self.version


@dataclass(frozen=True)
class Module:
    """One kernel module file to insert, in order."""

    name: str
    path: Path


def find_kernel(image: Path | None = None, boot: Path = Path("/boot")) -> Kernel:
    """The kernel to boot: ``image`` if given, else the newest ``boot/vmlinuz-*`` with modules.

    :raises VmUnavailable: no readable kernel image with a module tree.
    """
    if image is not None:
        if not image.is_file():
            raise VmUnavailable(f"kernel image {image} not found")
        version = image.name.removeprefix("vmlinuz-")
        kernel = Kernel(image, version)
        if not kernel.modules_dir.is_dir():
            raise VmUnavailable(f"kernel image {image} has no module tree {kernel.modules_dir}")
        return kernel
    candidates = [Kernel(p, p.name.removeprefix("vmlinuz-"))
                  for p in boot.glob("vmlinuz-*") if p.is_file()]
    candidates = [k for k in candidates if k.modules_dir.is_dir()]
    if not candidates:
        raise VmUnavailable(f"no kernel image with modules in {boot} "
                            "(apt-get install linux-image-amd64)")
    return max(candidates, key=lambda k: _version_key(k.version))


def _version_key(version: str) -> tuple[tuple[int, int | str], ...]:
    """Sort key for kernel versions: numeric parts compare as numbers ("6.10" > "6.9")."""
    return tuple((0, int(p)) if p.isdigit() else (1, p) for p in re.split(r"[.\-+~]", version))


def resolve_modules(kernel: Kernel, names: tuple[str, ...]) -> list[Module]:
    """Module files for ``names`` and their dependencies, in load order, without repeats.

    Uses ``modprobe -S <kver> --show-depends NAME`` once per name (modprobe reads
    further arguments as module parameters). Built-in modules need no file.

    :raises VmUnavailable: no ``modprobe`` on this machine.
    :raises VmFailure: a module is not in the kernel's module tree.
    """
    modprobe = shutil.which("modprobe") or next(
        (p for p in ("/usr/sbin/modprobe", "/sbin/modprobe") if os.access(p, os.X_OK)), None)
    if modprobe is None:
        raise VmUnavailable("modprobe not found (apt-get install kmod)")
    ordered: dict[Path, Module] = {}
    for name in names:
        proc = subprocess.run([modprobe, "-S", kernel.version, "--show-depends", name],
                              capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            detail = proc.stderr.strip().splitlines()[-1:] or ["no output"]
            raise VmFailure(f"module {name} missing for kernel {kernel.version}: {detail[0]}")
        for line in proc.stdout.splitlines():
            words = line.split()
            if len(words) >= 2 and words[0] == "insmod":
                path = Path(words[1])
                ordered.setdefault(path, Module(_module_name(path), path))
            # "builtin NAME": compiled into the kernel, nothing to load
    return list(ordered.values())


def _module_name(path: Path) -> str:
    name = path.name
    for suffix in (".xz", ".gz", ".zst"):
        name = name.removesuffix(suffix)
    return name.removesuffix(".ko")


def module_bytes(path: Path) -> bytes:
    """The module's ELF bytes, decompressed if the distribution ships it compressed.

    :raises VmFailure: a compression that busybox ``insmod`` cannot take and Python cannot undo.
    """
    data = path.read_bytes()
    if path.suffix == ".xz":
        return lzma.decompress(data)
    if path.suffix == ".gz":
        return gzip.decompress(data)
    if path.suffix == ".zst":
        zstd = shutil.which("zstd")
        if zstd is None:
            raise VmFailure(f"module {path} is zstd-compressed and zstd is not installed")
        return subprocess.run([zstd, "-dc", str(path)], capture_output=True, check=True).stdout
    return data


def static_busybox() -> Path:
    """The statically linked busybox for the initramfs.

    :raises VmUnavailable: none installed (``busybox-static`` provides it).
    """
    for candidate in (shutil.which("busybox"), "/bin/busybox", "/usr/bin/busybox"):
        if candidate and Path(candidate).is_file() and not _has_interpreter(Path(candidate)):
            return Path(candidate)
    raise VmUnavailable("no statically linked busybox (apt-get install busybox-static)")


def _has_interpreter(elf: Path) -> bool:
    """True when the 64-bit little-endian ELF file has a PT_INTERP segment (dynamic linking)."""
    with elf.open("rb") as fh:
        header = fh.read(64)
        if header[:4] != b"\x7fELF" or header[4] != 2 or header[5] != 1:
            return True  # not an x86-64 ELF: treat as unusable
        phoff, = struct.unpack_from("<Q", header, 0x20)
        phentsize, phnum = struct.unpack_from("<HH", header, 0x36)
        fh.seek(phoff)
        table = fh.read(phentsize * phnum)
    return any(struct.unpack_from("<I", table, i * phentsize)[0] == 3 for i in range(phnum))


def stage_initramfs(kernel: Kernel, stage: Path) -> list[Module]:
    """Fill the empty directory ``stage`` with the guest's initramfs tree; returns the modules.

    ``init`` (from ``init.sh``), ``bin/busybox``, the modules under
    ``lib/vcan-vm/`` and ``modules.order`` ("name file" per line, in load order).

    :raises VmUnavailable: no busybox-static.
    :raises VmFailure: a needed module is missing.
    """
    busybox = static_busybox()
    modules = resolve_modules(kernel, BOOT_MODULES + CAN_MODULES)
    (stage / "bin").mkdir(parents=True)
    (stage / "lib" / "vcan-vm").mkdir(parents=True)
    shutil.copy2(busybox, stage / "bin" / "busybox")
    order = []
    for i, module in enumerate(modules):
        file = f"{i:02d}-{module.name}.ko"
        (stage / "lib" / "vcan-vm" / file).write_bytes(module_bytes(module.path))
        order.append(f"{module.name} /lib/vcan-vm/{file}\n")
    (stage / "modules.order").write_text("".join(order))
    init = stage / "init"
    init.write_text(INIT_TEMPLATE.read_text())
    init.chmod(0o755)
    return modules


def pack_initramfs(stage: Path, out: Path) -> None:
    """Pack ``stage`` as an uncompressed newc cpio archive (the kernel takes it as is).

    :raises VmUnavailable: no ``cpio``.
    :raises VmFailure: cpio failed.
    """
    cpio = shutil.which("cpio")
    if cpio is None:
        raise VmUnavailable("cpio not found (apt-get install cpio)")
    names = sorted(str(p.relative_to(stage)) for p in stage.rglob("*"))
    with out.open("wb") as fh:
        proc = subprocess.run([cpio, "--quiet", "-o", "-H", "newc", "-R", "0:0"],
                              input="\n".join(names).encode(), stdout=fh, stderr=subprocess.PIPE,
                              cwd=stage, check=False)
    if proc.returncode != 0:
        raise VmFailure(f"cpio failed: {proc.stderr.decode(errors='replace').strip()}")


def build_initramfs(kernel: Kernel, stage: Path, out: Path) -> list[Module]:
    """:func:`stage_initramfs` into ``stage``, then :func:`pack_initramfs` to ``out``."""
    modules = stage_initramfs(kernel, stage)
    pack_initramfs(stage, out)
    return modules
