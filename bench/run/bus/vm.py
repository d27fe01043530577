"""Run commands next to a real vcan0 inside a virtme-ng micro-VM.

Many kernels (WSL2's, Docker Desktop's, CI containers', this project's own
machines) are built without CAN. Debian's stock kernel ships ``vcan.ko``; virtme-ng
boots it under QEMU with the host's root file system shared read-only and the
directories we name shared read-write, so the same binaries and the same
virtual environment run inside with a real SocketCAN ``vcan0``.

Recipe and costs: ``docs/VM.md``. Pitfalls handled here: ``virtme-run`` must be
on PATH, QEMU needs an open stdin and a pipe (not a file) for stdout, the exit
status of the guest command comes back through a file in a shared directory,
and almost no environment variable crosses into the guest.
"""

from __future__ import annotations

import os
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.paths import REPO, STATE
from bench.root import INSTALLED
from bench.stop import deferred

# Variables forwarded into the guest (everything else is dropped by virtme-ng).
FORWARD_ENV = ("CI", "TERM", "COLUMNS", "LINES", "PYTHONPATH", "PYTHONHASHSEED", "VIRTUAL_ENV", "NO_COLOR")
FORWARD_PREFIXES = ("BENCH_", "PYTEST_")
BAD_PATH_CHARS = (" ", ",", "=", "\t", "\n")


class VmError(RuntimeError):
    """The VM fallback cannot run here; the message says how to fix it."""


@dataclass
class VmOptions:
    cpus: int = 2
    memory: str = "2G"
    timeout_s: float = 3600.0
    kvm: bool = False
    interfaces: tuple[str, ...] = ("vcan0",)
    rwdirs: list[Path] = field(default_factory=list)
    # emulated CAN controllers on one emulated CAN bus (QEMU kvaser_pci: a Kvaser PCIcan, SJA1000), driven by
    # the guest's kvaser_pci driver as can0, can1, ... (link type `can`, down: the bench sets the bit rate)
    can_controllers: int = 0
    qemu_opts: list[str] = field(default_factory=list)  # more QEMU options (e.g. a serial port)


def vng_path() -> Path | None:
    """The `vng` of this Python's environment, else the one on PATH."""
    local = Path(sys.executable).parent / "vng"
    if local.exists():
        return local
    found = shutil.which("vng")
    return Path(found) if found else None


def find_kernel() -> tuple[Path, str] | None:
    """Newest /boot/vmlinuz-* whose modules include vcan.ko."""
    candidates = []
    for image in Path("/boot").glob("vmlinuz-*"):
        ver = image.name[len("vmlinuz-") :]
        mod_dir = Path("/lib/modules") / ver / "kernel" / "drivers" / "net" / "can"
        if any(mod_dir.glob("vcan.ko*")) and os.access(image, os.R_OK):
            candidates.append((image, ver))

    def key(item: tuple[Path, str]) -> list[object]:
        parts: list[object] = []
        for chunk in item[1].replace("-", ".").split("."):
            parts.append(int(chunk) if chunk.isdigit() else -1)
        return parts

    return max(candidates, key=key) if candidates else None


def readiness() -> list[tuple[str, bool, str]]:
    """(what, ok, detail or fix) for every piece the VM fallback needs."""
    items: list[tuple[str, bool, str]] = []
    vng = vng_path()
    items.append(
        ("virtme-ng (vng)", vng is not None, str(vng) if vng else "pip install virtme-ng==1.42 (make setup does it)")
    )
    qemu = shutil.which("qemu-system-x86_64")
    items.append(("qemu-system-x86_64", qemu is not None, qemu or "apt-get install qemu-system-x86"))
    kern = find_kernel()
    items.append(
        ("kernel with vcan.ko", kern is not None, f"{kern[0]}" if kern else "apt-get install linux-image-amd64")
    )
    busybox = shutil.which("busybox")
    items.append(("busybox (initramfs)", busybox is not None, busybox or "apt-get install busybox-static"))
    # the guest runs on this host's root file system: what the VM's scripts and virtme-ng run there (a slim
    # container image lacks them): `file` on busybox (is it static?), ip for the CAN box's namespaces, pkill
    for exe, what, pkg in (("file", "virtme-ng checks busybox", "file"), ("ip", "the box's namespaces", "iproute2")):
        found = shutil.which(exe)
        items.append((f"{exe} ({what})", found is not None, found or f"apt-get install {pkg}"))
    found = shutil.which("pkill")
    items.append(("pkill (the box's power-off)", found is not None, found or "apt-get install procps"))
    return items


def _check_path(p: Path) -> Path:
    p = p.resolve()
    if any(c in str(p) for c in BAD_PATH_CHARS):
        raise VmError(f"cannot share {p} with the VM: virtme-ng's --rwdir breaks on blanks, ',' and '='")
    return p


def can_bus_qemu_opts(controllers: int) -> list[str]:
    """QEMU options of `controllers` Kvaser PCIcan cards on one emulated CAN bus (QEMU docs/system/devices/
    can.rst): a frame one sends reaches the others, as on a bus with two USB adapters."""
    return ["-object can-bus,id=canbus0"] + ["-device kvaser_pci,canbus=canbus0"] * controllers


def _guest_script(
    cmd: list[str],
    cwd: Path,
    status_file: Path,
    interfaces: tuple[str, ...],
    can_controllers: int = 0,
    shared: tuple[Path, ...] = (),
) -> str:
    env_lines = []
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "/usr/bin:/bin")])
    env_lines.append(f"export PATH={shlex.quote(path)}")
    for key, value in os.environ.items():
        if key in FORWARD_ENV or key.startswith(FORWARD_PREFIXES):
            env_lines.append(f"export {key}={shlex.quote(value)}")
    # $HOME is read-only in the guest and /tmp is private to it: point caches there.
    env_lines += [
        "export HOME=/tmp/vmhome XDG_CACHE_HOME=/tmp/vmhome/.cache MPLCONFIGDIR=/tmp/vmhome/mpl",
        "export PYTHONDONTWRITEBYTECODE=1 BENCH_IN_VM=1",
        # an installed bench's working folder is the host's (shared), not the guest's own $HOME
        *([f"export BENCH_CACHE_DIR={shlex.quote(str(STATE))}"] if INSTALLED else []),
        # the folders that reach the host: a command's output elsewhere is refused (bench.paths.lost_in_vm)
        f"export BENCH_VM_SHARED={shlex.quote(os.pathsep.join(map(str, shared)))}",
        "mkdir -p /tmp/vmhome/.cache /tmp/vmhome/mpl",
    ]
    up = ["modprobe -a vcan can_raw can_bcm 2>/dev/null || modprobe -a vcan can_raw || exit 90"]
    if can_controllers:
        last = f"can{can_controllers - 1}"
        up.append(
            "modprobe -a kvaser_pci can_raw && for i in $(seq 50); do [ -e /sys/class/net/"
            f"{last} ] && break; sleep 0.1; done; [ -e /sys/class/net/{last} ] || {{ echo 'bench vm: "
            f"the emulated CAN controllers did not appear ({last})' >&2; echo 93 > {status_file}; exit 93; }}"
        )
    for name in interfaces:
        up.append(
            f"ip link add dev {name} type vcan && ip link set {name} mtu 72 txqueuelen 4000 && "
            f"ip link set up {name} || {{ echo 'bench vm: cannot create {name}' >&2; "
            f"echo 91 > {status_file}; exit 91; }}"
        )
    return "\n".join(
        [
            "#!/bin/sh",
            *up,
            *env_lines,
            f"cd {shlex.quote(str(cwd))} || exit 92",
            " ".join(shlex.quote(c) for c in cmd),
            f"echo $? > {shlex.quote(str(status_file))}",
            # Whatever the command left running in the background must not keep the VM alive.
            "sync",
            "(poweroff -f || echo o > /proc/sysrq-trigger) >/dev/null 2>&1",
            "",
        ]
    )


def run_in_vm(cmd: list[str], options: VmOptions | None = None, cwd: Path | None = None, stdout: object = None) -> int:
    """Boot the VM, bring up the vcan interfaces, run `cmd` in `cwd`, return its exit status.

    Output of the command is streamed to `stdout` (default: sys.stdout) while it runs.
    Returns 124 on timeout and 255 when the guest ended without reporting a status.
    """
    opts = options or VmOptions()
    missing = [f"{what}: {fix}" for what, ok, fix in readiness() if not ok]
    if missing:
        raise VmError("the VM fallback is not ready:\n  " + "\n  ".join(missing))
    kern = find_kernel()
    assert kern is not None
    vng = vng_path()
    assert vng is not None
    cwd = _check_path(cwd or Path.cwd())
    jobs = STATE / "vm"
    job = jobs / f"{time.strftime('%Y%m%d-%H%M%S')}-{uuid.uuid4().hex[:8]}"
    try:
        job.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise VmError(
            f"cannot make the VM's job folder {job}: {exc.strerror} (BENCH_CACHE_DIR chooses another)"
        ) from None
    status_file = job / "status"
    script = job / "job.sh"
    home = STATE if INSTALLED else REPO  # a clone is shared whole; a package only its working folder
    rwdirs = {_check_path(home)}
    if not cwd.is_relative_to(home):
        rwdirs.add(cwd)
    rwdirs.update(_check_path(p) for p in opts.rwdirs)
    script.write_text(
        _guest_script(cmd, cwd, status_file, opts.interfaces, opts.can_controllers, tuple(sorted(rwdirs)))
    )
    argv = _vng_argv(vng, kern[0], opts, rwdirs, script)
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(vng.parent), env.get("PATH", "")])
    out = stdout if stdout is not None else sys.stdout
    if _stream(argv, env, out, opts.timeout_s) is None:
        return 124
    if not status_file.exists():
        sys.stderr.write(
            "bench vm: the guest ended without reporting the command's status "
            "(killed by a signal, or the guest kernel failed); see the output above\n"
        )
        return 255
    status = int(status_file.read_text().strip() or "255")
    shutil.rmtree(job, ignore_errors=True)
    return status


# Modules the guest's udev would load for devices of QEMU's q35 machine (and the host CPU's) that no job uses: the
# SATA controller's probe, KVM (1 MB, ~6 s to load in an emulated guest), the watchdog, the crypto and input drivers.
# Refused by the kernel (module_blacklist=), a boot reaches the job in ~11 s instead of ~19 s on an idle 2-core host
# (docs/VM.md). The bench loads what it uses itself (vcan, can_raw, kvaser_pci ...: modprobe in the job).
UNUSED_MODULES = (
    "kvm,kvm_amd,kvm_intel,ccp,ahci,libahci,sr_mod,sg,iTCO_wdt,psmouse,pcspkr,i2c_i801,lpc_ich,serio_raw,evdev,"
    "aesni_intel,ghash_clmulni_intel,sha1_ssse3,sha256_ssse3,sha512_ssse3,crc32_pclmul,crc32c_intel,"
    "crct10dif_pclmul,powernow_k8"
)


def _vng_argv(vng: Path, kernel: Path, opts: VmOptions, rwdirs: set[Path], script: Path) -> list[str]:
    """virtme-ng's command line: the kernel, CPUs, memory, the shared folders, QEMU's extra devices, the job."""
    argv = [
        str(vng),
        "--run",
        str(kernel),
        "--append",
        f"module_blacklist={UNUSED_MODULES}",
        "--user",
        "root",
        "--cpus",
        str(opts.cpus),
        "--memory",
        opts.memory,
        "--force-9p",
    ]
    if not opts.kvm:
        argv.append("--disable-kvm")
    for d in sorted(rwdirs):
        argv += ["--rwdir", str(d)]
    for o in (can_bus_qemu_opts(opts.can_controllers) if opts.can_controllers else []) + opts.qemu_opts:
        argv.append(f"--qemu-opts={o}")  # with "=": the value starts with "-"
    argv += ["--exec", f"sh {script}"]
    return argv


def _stream(argv: list[str], env: dict[str, str], out: Any, timeout_s: float) -> int | None:
    """Run virtme-ng, its output streamed to `out` as it comes; its exit status, None on a timeout (the whole
    process group stopped: QEMU may outlive vng). Ctrl-C and SIGTERM stop it too, and are raised again."""
    # QEMU reopens its stdout: give it a pipe (never a file) and an open stdin.
    with subprocess.Popen(
        argv,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        start_new_session=True,
    ) as proc:
        assert proc.stdout is not None
        deadline = time.monotonic() + timeout_s
        expired = threading.Event()

        def _expire() -> None:  # enforced even when the guest prints nothing
            expired.set()
            try:
                os.killpg(proc.pid, 15)
            except ProcessLookupError:
                pass

        watchdog = threading.Timer(timeout_s, _expire)
        watchdog.daemon = True
        watchdog.start()
        try:
            for raw in iter(proc.stdout.readline, b""):
                out.write(raw.decode(errors="replace"))
                out.flush()
            if expired.is_set():
                raise subprocess.TimeoutExpired(argv, timeout_s)
            proc.wait(timeout=max(1.0, deadline - time.monotonic()))
        except (subprocess.TimeoutExpired, KeyboardInterrupt) as exc:  # Ctrl-C, SIGTERM (bench/stop.py), timeout
            watchdog.cancel()
            with deferred():  # a second signal must not leave QEMU behind
                _stop_group(proc)
            if isinstance(exc, KeyboardInterrupt):
                raise
            sys.stderr.write(f"bench vm: timed out after {timeout_s:.0f} s\n")
            return None
    watchdog.cancel()
    return proc.returncode


def _stop_group(proc: subprocess.Popen[bytes]) -> None:
    """End vng and everything it started (QEMU and its helpers: one process group, its own session):
    SIGTERM, then SIGKILL to what is left of the group, vng included, once vng ended or after 10 s."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # QEMU may outlive vng (it reparents to init, same group)
    except ProcessLookupError:
        pass
    proc.wait()
