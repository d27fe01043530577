"""`bench doctor`: one screen telling what the bench found on this machine."""

from __future__ import annotations

import importlib.metadata
import os
import shutil
import subprocess
from dataclasses import dataclass

from bench import canbus, extras, mcu
from bench.paths import BIN, MISSING_BUILD
from bench.root import INSTALLED
from bench.run import vm_readiness


@dataclass
class Check:
    name: str
    ok: bool
    detail: str
    fix: str = ""
    optional: bool = False


def _version(cmd: list[str]) -> str | None:
    if not shutil.which(cmd[0]):
        return None
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=10).stdout
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.splitlines()[0].strip() if out else None


def _py_version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


# Tools whose path is shown rather than a version line (candump prints none)
WHICH_ONLY = ("candump (can-utils)",)


def collect() -> tuple[list[Check], str]:
    """All checks, and the way CAN work will run here ('host', 'box', 'vm' or 'none')."""
    checks: list[Check] = []
    af = canbus.probe_af_can()
    checks.append(
        Check(
            "kernel CAN (AF_CAN)",
            af.af_can,
            af.detail,
            "" if af.af_can else "none on this kernel: the VM fallback below provides real SocketCAN",
            optional=True,
        )
    )
    state = canbus.interface_state("vcan0")
    checks.append(
        Check(
            "vcan0 on the host",
            state == "up",
            state or "absent",
            ""
            if state == "up" or not af.af_can
            else "sudo modprobe vcan && sudo ip link add dev vcan0 type vcan mtu 72 && sudo ip link set up vcan0",
            optional=True,
        )
    )
    vm_items = vm_readiness()
    vm_ok = all(ok for _, ok, _ in vm_items)
    for what, ok, detail in vm_items:
        checks.append(
            Check(f"VM fallback: {what}", ok, detail if ok else "missing", "" if ok else detail, optional=af.af_can)
        )
    checks.append(Check(extras.DIST, True, f"{_py_version(extras.DIST) or 'source'} from {extras.describe_origin()}"))
    for dist in ("python-can", "canopen", "numpy", "virtme-ng"):  # the package's own dependencies
        ver = _py_version(dist)
        checks.append(Check(dist, ver is not None, ver or "not installed", "" if ver else _install_hint(dist)))
    checks += [extra_check(extra) for extra in extras.EXTRAS]
    for label, cmd, optional, pkg in (
        ("gcc", ["gcc", "--version"], False, "gcc"),
        ("clang (fuzzing)", ["clang", "--version"], True, "clang libclang-rt-14-dev"),
        (
            "arm-none-eabi-gcc (Cortex-M4F build)",
            ["arm-none-eabi-gcc", "--version"],
            True,
            "gcc-arm-none-eabi libnewlib-arm-none-eabi",
        ),
        ("candump (can-utils)", ["candump", "-h"], True, "can-utils"),
        ("cyclictest (rt-tests)", ["cyclictest", "--help"], True, "rt-tests"),
    ):
        ver = _version(cmd) if label not in WHICH_ONLY else shutil.which(cmd[0])
        checks.append(
            Check(
                label, ver is not None, ver or "not found", "" if ver else f"apt-get install {pkg}", optional=optional
            )
        )
    built = (BIN / "can_pingpong").exists()
    where = f"{BIN} ({'installed package' if INSTALLED else 'clone'})"
    checks.append(Check("C build", built, where if built else "not built", "" if built else MISSING_BUILD))
    image = mcu.ELF.exists()
    fix = (
        "apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi, then reinstall pmsm-hil-bench"
        if INSTALLED
        else "make mcu (needs gcc-arm-none-eabi)"
    )
    detail = str(mcu.ELF) if image else "not built"
    checks.append(Check("Cortex-M4F image (--drive mcu)", image, detail, "" if image else fix, optional=True))
    if canbus.host_has_vcan():
        mode = "host"
    elif vm_ok and os.environ.get("BENCH_BOX") != "0":
        mode = "box"
    elif vm_ok:
        mode = "vm"
    else:
        mode = "none"
    return checks, mode


def _box_state() -> str:
    """The CAN box's state in one line (bench box status says more)."""
    from bench.run import box_status

    st = box_status()
    if st["state"] == "down":
        last = st.get("last_end")
        return f"down (the next vcan run boots it, {_next_accel()}; or `bench box up`)" + (
            f"; last: {last['why']}" if last else ""
        )
    if st["state"] == "stopping":
        return f"stopping ({st['why']})"
    used = sum(1 for x in st.get("slots", []) if x.get("in_use"))
    return (
        f"{st['state']} on {st.get('accel', 'tcg').upper()} ({st.get('accel_why', '')}), up {st['up_s']:.0f} s, "
        f"{used} of {len(st.get('slots', []))} slots in use, powers off after {st['idle_timeout_s']:g} s unused "
        "(`bench box status` lists the slots' python-can channels)"
    )


def _next_accel() -> str:
    """Which accelerator the next boot uses, and why."""
    from bench.run import box_next_accel

    try:
        kvm, why = box_next_accel()
    except ValueError as exc:
        return str(exc)
    return f"trying KVM first ({why})" if kvm else f"on TCG, ~15-60 s ({why})"


def report() -> int:
    checks, mode = collect()
    width = max(len(c.name) for c in checks) + 2
    print("bench doctor: what this machine offers the bench\n")
    for c in checks:
        mark = "ok " if c.ok else ("-- " if c.optional else "NO ")
        print(f"  [{mark}] {c.name:<{width}} {c.detail}")
        if not c.ok and c.fix:
            print(f"        {'':<{width}} fix: {c.fix}")
    print()
    if mode == "host":
        print("CAN work runs on the host's own SocketCAN (vcan0).")
    elif mode == "box":
        print(
            "The host kernel has no usable SocketCAN: vcan runs go to the CAN box, one VM booted once whose buses "
            "the bench's Python on this host reaches over SLCAN (docs/VM.md)."
        )
        print(f"CAN box: {_box_state()}")
    elif mode == "vm":
        print(
            "The host kernel has no usable SocketCAN: CAN work runs in the virtme-ng VM fallback "
            "(ready; `bench vm -- CMD` runs CMD next to a real vcan0)."
        )
    else:
        print(
            "No SocketCAN and no VM fallback: install what the 'VM fallback' lines above name"
            + ("." if INSTALLED else " (`make setup` does it in a clone).")
        )
    absent = [c.name for c in checks if c.name.startswith("[") and not c.ok]
    if absent:
        print(
            f"Optional, not installed: {', '.join(absent)} (not a problem: the runs work without; each line says "
            f"how to add it{_keeping_numpy()})."
        )
    problems = [c for c in checks if not c.ok and not c.optional]
    if problems:
        print(f"{len(problems)} problem(s) above; each line says the command that fixes it.")
    return 0 if mode != "none" and not problems else 1


def _keeping_numpy() -> str:
    numpy = _py_version("numpy")
    return f", your numpy {numpy} kept" if numpy and INSTALLED else ""


def extra_check(extra: str) -> Check:
    """One of the package's extras (bench/extras.py): optional, its distributions' versions, and when one is missing
    the line that adds the extra from where the bench came, the installed numpy pinned (extras.install_command)."""
    versions = {d: _py_version(d) for d in extras.DISTS[extra]}
    ok = all(versions.values())
    have = ", ".join(f"{d} {v or 'not installed'}" for d, v in versions.items())
    fix = "" if ok else extras.install_command(extra) if INSTALLED else "make setup  (every extra, requirements.lock's)"
    return Check(f"[{extra}] extra", ok, have if ok else f"{have}; optional: {extras.PURPOSE[extra]}", fix, True)


def _install_hint(dist: str) -> str:
    """How to install a missing dependency: for an installed package (a pip user has no Makefile) the bench again from
    where it came, which brings its dependencies, the installed numpy pinned; `make setup` in a clone (its pinned set
    in .venv)."""
    if INSTALLED:
        return extras.install_command()
    return f"make setup  (installs the pinned {dist} into .venv)"
