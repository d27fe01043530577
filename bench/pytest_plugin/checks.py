"""The checks before a run: the bus is there (or the VM can supply it), with candump to record it; a law builds
(once per session and folder). Each problem is one message with its fix: at the session's start pytest prints it
as "ERROR: ..." and runs nothing; a hil marker's turns it into the test's skip reason."""

from __future__ import annotations

import argparse
import os
import re
import shutil
from pathlib import Path

from bench.pytest_plugin.state import LawBuild, Settings

IFNAME = re.compile(r"[A-Za-z][A-Za-z0-9_.:-]{0,14}")  # a Linux interface name (IFNAMSIZ 16, with its NUL)


def bus_problem(bus: str, option: str = "--hil-bus", drive: str = "node") -> str | None:
    """What stops `bench run --bus BUS` here, said as `bench run` would (bench.run.bus.buses) with the
    plugin's option, or None. On a host without kernel CAN a vcan/can bus runs in the VM: then the VM's
    missing pieces, each with the command that installs it."""
    from bench.run.bus.buses import choose_bus

    kind = choose_bus(bus, box=False)  # the CAN box is asked below, once the bus is known to be one
    if drive == "mcu" and kind.in_process:
        return f"--drive mcu needs a CAN bus (the image's UART joins one in the VM), not {option} {bus}"
    if kind.in_process:
        return None
    if not IFNAME.fullmatch(bus):
        return f"{option} {bus!r}: not a bus: 'direct' or a CAN interface name (vcan0, can0, ...)"
    from bench.run.bus.buses import bus_problem as run_bus_problem

    args = argparse.Namespace(bus=bus, drive_bus=None, no_drive=False, drive=drive, interface="socketcan", bitrate=None)
    problem, in_vm = run_bus_problem(args)
    if problem:
        text = problem.replace(f"--bus {bus}", f"{option} {bus}", 1).replace("use --bus direct", "use the direct bus")
        if "no such CAN interface" in text:
            text += _create_hint(bus, kind.virtual)
        return text
    if shutil.which("candump") is None:
        return (
            f"{option} {bus}: candump (can-utils) is not installed: every SocketCAN run records its bus with it "
            "(Debian/Ubuntu: apt-get install can-utils)"
        )
    in_vm = in_vm or choose_bus(bus).box_why() is not None  # the CAN box is a VM too: the same pieces
    if in_vm and not kind.virtual and drive != "mcu":
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


def _create_hint(bus: str, virtual: bool) -> str:
    if virtual:
        return f" (create it: sudo ip link add dev {bus} type vcan mtu 72 && sudo ip link set up {bus})"
    return " (`ip -details link show` lists this machine's interfaces)"


def law_build(settings: Settings, law: Path, option: str) -> LawBuild:
    """The session's build of a law folder: `make LAW=law` (bench/law.py) the first time it is asked for, and
    again only in a new session; a folder whose content changed since is refused (the runs of one session use
    one build of it). LawBuildError's message, or the change, as `option`'s refusal."""
    from bench.law import LawBuildError, build, digest, law_name, law_names_of

    try:
        if not law.is_dir():
            raise LawBuildError(f"{law}: no such folder")
        now = digest(law)  # before the build: an edit while it runs is a change the next call refuses
        known = settings.laws.get(law)
        if known is not None and known.digest != now:
            raise LawBuildError(
                f"the folder changed during this pytest session (built from its content of {known.digest}, now "
                f"{now}); its runs in one session use one build: start a new session to build the change"
            )
        if known is None:
            out = build(law)
            known = settings.laws[law] = LawBuild(law, out, law_name(law), now, ",".join(law_names_of(law)))
        return known
    except LawBuildError as exc:
        raise LawRefusal(f"{option} {law}: {exc}") from None
    except OSError as exc:
        raise LawRefusal(f"{option} {law}: cannot read the folder: {exc.strerror} ({exc.filename})") from None


class LawRefusal(Exception):
    """A law the session cannot use: the message names the option, the folder and why."""


def use_law(settings: Settings, law: Path) -> dict[str, str | None]:
    """The session's default law (--hil-law) built, and this process's environment pointed at its build, which
    the `bench run` children inherit (BENCH_BUILD_DIR: bench/paths.py). The runs need not select it (a test of a
    built-in law runs in the law's build, which has them all). The former values, to restore at the end."""
    import pytest

    before = {k: os.environ.get(k) for k in ("BENCH_BUILD_DIR", "BENCH_LAW")}
    try:
        built = law_build(settings, law, "--hil-law")
    except LawRefusal as exc:
        raise pytest.UsageError(str(exc)) from None
    os.environ["BENCH_BUILD_DIR"] = str(built.out)
    os.environ.pop("BENCH_LAW", None)
    return before


def restore(env: dict[str, str | None]) -> None:
    for k, v in env.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
