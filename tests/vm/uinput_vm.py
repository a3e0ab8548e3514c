"""Boot a real Debian kernel under QEMU (software emulation) to test the uinput touchscreen.

Facts this relies on are in the team's uinput-vm notes (summarised in docs/uinput.md): the host's
root is shared read-only over virtio-9p, a tiny initramfs loads the virtio, 9p, evdev and uinput
modules, chroots into the host's root and runs a shell script given on the kernel command line
(``dt_script=PATH``); results come back on the serial console only.

Assets (vmlinuz, 12 modules, the initramfs) are built from Debian packages into a cache folder
outside the repository: ``$DEPTHTOUCH_CACHE/vm`` or ``<repo>/.cache/depthtouch/vm``. Run this file
to build them (``python tests/vm/uinput_vm.py``); :func:`ensure_assets` does it on demand.
Needs: ``apt-get``/``apt-cache``/``dpkg-deb`` (the kernel .deb is downloaded, not installed),
``busybox-static`` and ``qemu-system-x86``.
"""

from __future__ import annotations

import gzip
import io
import os
import re
import shutil
import subprocess
import sys
import tarfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
QEMU = "qemu-system-x86_64"
BUSYBOX_PATHS = ("/bin/busybox", "/usr/bin/busybox")
# load order matters: each module after the ones it depends on
MODULES = ("virtio_ring", "virtio", "virtio_pci_modern_dev", "virtio_pci_legacy_dev",
           "virtio_pci", "9pnet", "9pnet_virtio", "netfs", "fscache", "9p", "evdev", "uinput")
MARK = "DT-VM:"

INIT = """#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in {modules}; do
  insmod /modules/$m.ko || echo "{mark} insmod $m failed"
done
if ! mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=512000,cache=loose hostroot /host; then
  echo "{mark} 9p mount failed"; poweroff -f
fi
mount -t proc proc /host/proc
mount -t sysfs sys /host/sys
mount -t devtmpfs dev /host/dev
mount -t tmpfs tmp /host/run
script=$(sed -n 's/.*dt_script=\\([^ ]*\\).*/\\1/p' /proc/cmdline)
echo "{mark} booted $(cut -d' ' -f1 /proc/uptime)"
chroot /host /bin/sh "$script"
echo "{mark} script exit $? at $(cut -d' ' -f1 /proc/uptime)"
poweroff -f
"""


class Unavailable(Exception):
    """QEMU, busybox-static or the kernel package cannot be had here; the message says why."""


def cache_dir() -> Path:
    root = os.environ.get("DEPTHTOUCH_CACHE")
    return (Path(root) if root else REPO / ".cache" / "depthtouch") / "vm"


@dataclass(frozen=True)
class Assets:
    kernel: Path
    initramfs: Path
    release: str


def kernel_release() -> str:
    """The ``uname -r`` of Debian's current ``linux-image-amd64`` (e.g. ``6.1.0-50-amd64``)."""
    try:
        out = subprocess.run(["apt-cache", "show", "linux-image-amd64"], capture_output=True,
                             text=True, timeout=60).stdout
    except (OSError, subprocess.TimeoutExpired) as e:
        raise Unavailable(f"apt-cache cannot be run ({e}); a Debian host is needed") from e
    m = re.search(r"^Depends:.*?linux-image-(\S+-amd64)\b", out, re.M)
    if not m:
        raise Unavailable("apt-cache knows no linux-image-amd64; run apt-get update")
    return m.group(1)


def _download_deb(release: str, folder: Path) -> Path:
    found = sorted(folder.glob(f"linux-image-{release}_*.deb"))
    if found:
        return found[-1]
    folder.mkdir(parents=True, exist_ok=True)
    try:
        r = subprocess.run(["apt-get", "download", "-q", f"linux-image-{release}"], cwd=folder,
                           capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise Unavailable(f"apt-get download of the kernel failed ({e})") from e
    found = sorted(folder.glob(f"linux-image-{release}_*.deb"))
    if r.returncode != 0 or not found:
        raise Unavailable(f"apt-get download linux-image-{release} failed: "
                          f"{(r.stderr or r.stdout).strip()[-300:]}")
    return found[-1]


def _extract(deb: Path, release: str, out: Path) -> tuple[Path, dict[str, bytes]]:
    """vmlinuz into ``out`` and the wanted modules' bytes, streamed from ``dpkg-deb``."""
    proc = subprocess.Popen(["dpkg-deb", "--fsys-tarfile", str(deb)], stdout=subprocess.PIPE)
    assert proc.stdout is not None
    kernel = out / f"vmlinuz-{release}"
    modules: dict[str, bytes] = {}
    with tarfile.open(fileobj=proc.stdout, mode="r|*") as tar:
        for m in tar:
            name = m.name.lstrip("./")
            if not m.isfile():
                continue
            base = name.rsplit("/", 1)[-1]
            if name == f"boot/vmlinuz-{release}":
                f = tar.extractfile(m)
                assert f is not None
                kernel.write_bytes(f.read())
            elif "/kernel/" in name and base.endswith(".ko") and base[:-3] in MODULES:
                f = tar.extractfile(m)
                assert f is not None
                modules[base[:-3]] = f.read()
    proc.wait()
    missing = [m for m in MODULES if m not in modules]
    if not kernel.exists() or missing:
        raise Unavailable(f"{deb.name} lacks vmlinuz or modules {missing}")
    return kernel, modules


def _cpio_newc(entries: list[tuple[str, int, bytes, int, int]]) -> bytes:
    """A newc cpio archive of (name, mode, data, rdev_major, rdev_minor) entries."""
    buf = io.BytesIO()

    def pad(n: int) -> None:
        buf.write(b"\0" * ((4 - n % 4) % 4))

    for ino, (name, mode, data, major, minor) in enumerate(
            [*entries, ("TRAILER!!!", 0, b"", 0, 0)], start=1):
        fields = [ino, mode, 0, 0, 1, 0, len(data), 0, 0, major, minor, len(name) + 1, 0]
        head = b"070701" + b"".join(b"%08X" % v for v in fields)
        buf.write(head + name.encode() + b"\0")
        pad(len(head) + len(name) + 1)
        buf.write(data)
        pad(len(data))
    return buf.getvalue()


def _busybox() -> bytes:
    for p in BUSYBOX_PATHS:
        if os.path.exists(p):
            data = Path(p).read_bytes()
            if b"/ld-linux" in data:
                continue  # a dynamically linked busybox cannot run in the bare initramfs
            return data
    raise Unavailable("no static busybox; apt-get install busybox-static")


def build_initramfs(modules: dict[str, bytes], out: Path) -> Path:
    d, f = 0o040755, 0o100755
    entries = [(n, d, b"", 0, 0) for n in ("bin", "dev", "proc", "sys", "host", "modules")]
    entries.append(("dev/console", 0o020600, b"", 5, 1))
    entries.append(("bin/busybox", f, _busybox(), 0, 0))
    entries.append(("init", f, INIT.format(modules=" ".join(MODULES), mark=MARK).encode(), 0, 0))
    entries += [(f"modules/{m}.ko", 0o100644, modules[m], 0, 0) for m in MODULES]
    path = out / "initramfs.cpio.gz"
    tmp = path.with_suffix(".part")
    tmp.write_bytes(gzip.compress(_cpio_newc(entries), compresslevel=1))
    os.replace(tmp, path)
    return path


def ensure_assets(folder: Path | None = None) -> Assets:
    """The kernel and initramfs, built once into the cache (Unavailable says what is missing)."""
    if shutil.which(QEMU) is None:
        raise Unavailable(f"{QEMU} not found; apt-get install qemu-system-x86")
    folder = folder or cache_dir()
    release = kernel_release()
    kernel = folder / f"vmlinuz-{release}"
    initramfs = folder / "initramfs.cpio.gz"
    stamp = folder / f"initramfs-{release}.ok"
    if kernel.exists() and initramfs.exists() and stamp.exists():
        return Assets(kernel, initramfs, release)
    folder.mkdir(parents=True, exist_ok=True)
    deb = _download_deb(release, folder)
    kernel, modules = _extract(deb, release, folder)
    build_initramfs(modules, folder)
    stamp.write_text(INIT)
    return Assets(kernel, initramfs, release)


@dataclass(frozen=True)
class BootResult:
    lines: list[str]
    seconds: float
    booted_s: float | None  # guest uptime when /init reached the script
    timed_out: bool


def boot(assets: Assets, script: Path, timeout_s: float = 300.0, memory: str = "768M"
         ) -> BootResult:
    """Boot, run ``script`` (a host path; /bin/sh in the host's root) and power off.

    Returns the serial console's lines. QEMU is killed by its PID after ``timeout_s``.
    """
    # -cpu max: the default qemu64 model lacks SSE4.2/AVX, which numpy's wheels need (SIGILL)
    cmd = [QEMU, "-accel", "tcg", "-cpu", "max", "-m", memory, "-smp", "1", "-nodefaults",
           "-display", "none", "-no-reboot", "-kernel", str(assets.kernel), "-initrd", str(assets.initramfs),
           "-append", f"console=ttyS0 panic=-1 quiet dt_script={script}",
           "-virtfs", "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,"
                      "multidevs=remap",
           "-serial", "stdio", "-monitor", "none"]
    t0 = time.monotonic()
    out_path = script.with_name(script.name + ".console")
    with out_path.open("wb") as out:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT)
        try:
            proc.wait(timeout=timeout_s)
            timed_out = False
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            timed_out = True
    seconds = time.monotonic() - t0
    text = out_path.read_bytes().decode("utf-8", "replace").replace("\r", "")
    lines = text.splitlines()
    booted = None
    for ln in lines:
        if ln.startswith(f"{MARK} booted "):
            booted = float(ln.split()[-1])
    return BootResult(lines, seconds, booted, timed_out)


if __name__ == "__main__":
    a = ensure_assets()
    print(f"kernel {a.kernel}\ninitramfs {a.initramfs} ({a.initramfs.stat().st_size} bytes)",
          file=sys.stderr)
