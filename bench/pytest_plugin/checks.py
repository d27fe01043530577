"""The session's checks before any test: the bus is there (or the VM can supply it), the user's law builds.
Each problem is one message with its fix (pytest prints it as "ERROR: ..." and runs nothing)."""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path

IFNAME = re.compile(r"[A-Za-z][A-Za-z0-9_.:-]{0,14}")  # a Linux interface name (IFNAMSIZ 16, with its NUL)


def bus_problem(bus: str, option: str = "--hil-bus") -> str | None:
    """What stops `bench run --bus BUS` here, said as `bench run` would (bench.run.bus.buses) with the
    plugin's option, or None. On a host without kernel CAN a vcan/can bus runs in the VM: then the VM's
    missing pieces, each with the command that installs it."""
    if bus == "direct":
        return None
    if not IFNAME.fullmatch(bus):
        return f"{option} {bus!r}: not a bus: 'direct' or a CAN interface name (vcan0, can0, ...)"
    from bench.run.bus.buses import bus_problem as run_bus_problem

    args = argparse.Namespace(
        bus=bus, drive_bus=None, no_drive=False, drive="node", interface="socketcan", bitrate=None
    )
    problem, in_vm = run_bus_problem(args)
    if problem:
        text = problem.replace(f"--bus {bus}", f"{option} {bus}", 1).replace("use --bus direct", "use the direct bus")
        if "no such CAN interface" in text:
            text += _create_hint(bus)
        return text
    if in_vm and not bus.startswith("vcan"):
        return (
            f"{option} {bus}: this host's kernel has no SocketCAN, so there is no {bus} here; `bench run --bus {bus}` "
            "would run an emulated CAN controller in the bench's VM, not a physical adapter: use vcan0 (or direct) "
            f"on this host, and {bus} on a host that has the adapter"
        )
    if in_vm:
        from bench.run.bus.vm import readiness

        missing = [f"{what}: {fix}" for what, ok, fix in readiness() if not ok]
        if missing:
            return (
                f"{option} {bus}: this host's kernel has no SocketCAN, so the bus runs in the virtme-ng VM, whose "
                "fallback is not ready (bench doctor says more):\n  " + "\n  ".join(missing)
            )
    return None


def _create_hint(bus: str) -> str:
    if bus.startswith("vcan"):
        return f" (create it: sudo ip link add dev {bus} type vcan && sudo ip link set up {bus})"
    return " (`ip -details link show` lists this machine's interfaces)"


def build_law(law: Path) -> tuple[Path, str]:
    """`make LAW=law` (bench/law.py): (its build folder, the law's name), or the refusal as a UsageError."""
    import pytest

    from bench.law import LawBuildError, build, law_name

    try:
        out = build(law)
    except LawBuildError as exc:
        raise pytest.UsageError(f"--hil-law {law}: {exc}") from None
    return out, law_name(law)


def use_law(law: Path) -> dict[str, str | None]:
    """Build the law and point the runs at it as `bench run --law` does (bench/law.py use()): BENCH_BUILD_DIR and
    BENCH_LAW in this process's environment, which its `bench run` children inherit. The former values, to
    restore at the session's end."""
    before = {k: os.environ.get(k) for k in ("BENCH_BUILD_DIR", "BENCH_LAW")}
    out, name = build_law(law)
    os.environ["BENCH_BUILD_DIR"] = str(out)
    os.environ["BENCH_LAW"] = name
    return before


def restore(env: dict[str, str | None]) -> None:
    for k, v in env.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
