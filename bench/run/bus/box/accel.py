"""Which accelerator runs the CAN box: KVM where it works, else QEMU's TCG emulation (issue 56).

A box boots with KVM when `/dev/kvm` is usable and KVM has not already failed on this host; the keeper gives the
KVM guest a deadline (KVM_DEADLINE_S, BENCH_BOX_KVM_DEADLINE_S) to raise its links. A guest that does not come up
in time, or a QEMU that ends (on this development machine: "failed to set MSR 0x10a", within a second), is stopped
and the box boots on TCG; the failure is recorded in STATE/box/kvm.json with the host kernel and the QEMU binary it
was seen with, so that the next boots go straight to TCG and do not pay the deadline again. Another kernel or QEMU,
or `bench box up --accel kvm`, tries KVM again; `--accel tcg` (or BENCH_BOX_ACCEL=tcg) never tries.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

ACCEL_ENV = "BENCH_BOX_ACCEL"  # auto (default), kvm, tcg: as `bench box up --accel`
DEADLINE_ENV = "BENCH_BOX_KVM_DEADLINE_S"
CHOICES = ("auto", "kvm", "tcg")
# A KVM guest raises the box's links in a few seconds; a TCG one in 25-60 s. A KVM guest that is not up by then
# is taken as broken (a hang seen with `-cpu host,-arch-capabilities` on hosts like this one).
KVM_DEADLINE_S = 30.0
KVM_DEVICE = Path("/dev/kvm")
RECORD = "kvm.json"
FAILED = "KVM tried and failed"  # how BoxInfo.accel_why of a box that fell back to TCG starts


@dataclass(frozen=True)
class Plan:
    try_kvm: bool
    why: str  # why KVM is tried, or why not: said by `bench box status` and the boot's line


def choice(given: str | None = None) -> str:
    """The accelerator asked for: `given` (bench box up --accel), else BENCH_BOX_ACCEL, else auto."""
    value = (given or os.environ.get(ACCEL_ENV) or "auto").strip().lower()
    if value not in CHOICES:
        raise ValueError(f"{ACCEL_ENV}={value!r}: the accelerator is one of {', '.join(CHOICES)}")
    return value


def deadline_s() -> float:
    """Seconds a KVM guest has to come up (BENCH_BOX_KVM_DEADLINE_S, default KVM_DEADLINE_S)."""
    raw = os.environ.get(DEADLINE_ENV)
    if not raw:
        return KVM_DEADLINE_S
    try:
        value = float(raw)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise ValueError(f"{DEADLINE_ENV}={raw!r}: seconds, > 0")
    return value


def kvm_unusable(device: Path = KVM_DEVICE) -> str | None:
    """Why this process cannot open KVM's device, or None when it can."""
    if not device.exists():
        return f"{device} does not exist (no KVM in this kernel or container)"
    if not os.access(device, os.R_OK | os.W_OK):
        return f"{device} is not readable and writable by this user (add it to the group `kvm`)"
    return None


def host_key() -> dict[str, str]:
    """What a recorded KVM failure holds for: this host's kernel and the QEMU binary (another retries)."""
    qemu = shutil.which("qemu-system-x86_64") or ""
    try:
        stamp = str(int(Path(qemu).stat().st_mtime)) if qemu else ""
    except OSError:
        stamp = ""
    return {"kernel": platform.release(), "qemu": qemu, "qemu_mtime": stamp}


def recorded_failure(box_dir: Path) -> str | None:
    """The reason KVM failed on this host before (same kernel, same QEMU), or None."""
    try:
        rec = json.loads((box_dir / RECORD).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(rec, dict) or rec.get("host") != host_key():
        return None
    return str(rec.get("why") or "unknown")


def record_failure(box_dir: Path, why: str) -> None:
    box_dir.mkdir(parents=True, exist_ok=True)
    rec = {"why": why, "at": time.time(), "host": host_key()}
    (box_dir / RECORD).write_text(json.dumps(rec, indent=1) + "\n")


def forget_failure(box_dir: Path) -> None:
    (box_dir / RECORD).unlink(missing_ok=True)


def plan(box_dir: Path, asked: str, device: Path = KVM_DEVICE) -> Plan:
    """Whether this boot tries KVM, and why (or why not)."""
    if asked == "tcg":
        return Plan(False, f"TCG asked for ({ACCEL_ENV}=tcg or --accel tcg)")
    unusable = kvm_unusable(device)
    if unusable is not None:
        return Plan(False, f"no KVM: {unusable}")
    failed = recorded_failure(box_dir)
    if failed is not None and asked == "auto":
        return Plan(False, f"KVM failed on this host before ({failed}); `bench box up --accel kvm` tries again")
    return Plan(True, "KVM asked for" if asked == "kvm" else f"{device} is usable")
