"""`bench run` on a host without SocketCAN: the bus half runs in the virtme-ng VM (`bench capture`: nodes,
master, candump), the host decodes candump's log on the shared folder as it grows."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

from bench.run.bus.buses import vm_links
from bench.run.outputs import Outputs
from bench.scenario import Scenario, ScenarioError, load

CAPTURE_REFUSED = 65  # `bench capture` in the VM: a node refused a value of the scenario (EX_DATAERR)
CAPTURE_LINK = 66  # `bench capture` in the VM: a CAN link could not be set up (canbus.LinkError)
GUEST_TTY = "/dev/ttyS1"  # the VM's second 16550 (ttyS0 is virtme-ng's console): the MCU image's UART0


def run_in_vm_capture(args: argparse.Namespace, sc: Scenario, partial: Path, outputs: Outputs) -> Any:
    """The bus half runs in the VM (`bench capture`: nodes, master, candump); the host follows
    candump's log on the shared folder and feeds the same pipeline as it grows (live view included)."""
    import uuid

    from bench.paths import STATE
    from bench.run.bus.vm import run_in_vm
    from bench.run.pipeline import Pipeline
    from bench.run.record.sources import LogFollower

    # The guest's /tmp is its own: stage the capture in the bench's working folder (always shared with the VM).
    stage = STATE / "capture" / uuid.uuid4().hex[:12]
    stage.mkdir(parents=True)
    pipe = Pipeline(args.plant_id, args.drive_id, outputs.sinks, outputs.frame_sinks, sc.expect)
    follower = LogFollower(stage / "candump.log")
    stop = threading.Event()
    errors: list[BaseException] = []

    def follow() -> None:
        try:
            while not stop.wait(0.5):
                pipe.feed(follower.drain())
                bar.update(pipe.periods - bar.n)
        except BaseException as exc:  # noqa: BLE001 - reported by the main thread
            errors.append(exc)

    cmd = _capture_command(args, stage)
    vm = vm_options(args)
    mcu = _start_mcu(vm, cmd) if getattr(args, "drive", "node") == "mcu" else None
    print(
        "bench run: host kernel has no SocketCAN; the bus runs inside the virtme-ng VM (boot ~20 s); "
        "the host decodes candump's log as it grows",
        flush=True,
    )
    t0 = time.monotonic()
    try:
        with outputs.progress(sc.periods, "run (VM)") as bar:
            th = threading.Thread(target=follow, daemon=True, name="bench-follow")
            th.start()
            try:
                rc = run_in_vm(cmd, vm, stdout=_Quiet())
            finally:
                stop.set()
                th.join()
            if errors:
                raise errors[0]
            _raise_for(rc)
            pipe.feed(follower.drain(final=True))
            bar.update(pipe.periods - bar.n)
        if not (stage / "capture.json").exists():
            raise RuntimeError("the capture inside the VM ended without saying how (no capture.json)")
        cap = json.loads((stage / "capture.json").read_text())
        (stage / "capture.json").unlink(missing_ok=True)
    finally:  # what was recorded goes with the run (NAME.failed when it failed)
        if mcu is not None:
            (stage / "drive_mcu.out").write_text(mcu.console())
            mcu.stop()
        for f in stage.iterdir():  # candump.log (-> bus.log) and the node processes' output
            shutil.move(str(f), partial / f.name)
        stage.rmdir()
    injected = None
    if sc.faults:  # the gateway's log of actions came with the capture
        from bench.run.bus.gateway import LOG_NAME, read_log

        injected = (sc.faults, *read_log(partial / LOG_NAME))
    return pipe.finish(
        sc.name,
        args.bus,
        {"wall_s": time.monotonic() - t0, "run_wall_s": cap.get("run_wall_s", 0.0)},
        cap.get("stopped"),
        cap.get("links"),
        injected,
    )


def _capture_command(args: argparse.Namespace, stage: Path) -> list[str]:
    """`bench capture` as the VM runs it: the run's scenario, bus, node-IDs and settings, its log in `stage`."""
    cmd = [sys.executable, "-m", "bench.cli", "capture", str(args.scenario.resolve()), "--bus", args.bus]
    cmd += ["--out", str(stage), "--plant-id", str(args.plant_id), "--drive-id", str(args.drive_id)]
    if args.drive_bus:
        cmd += ["--drive-bus", args.drive_bus]
    if args.bitrate:
        cmd += ["--bitrate", str(args.bitrate)]
    for o in args.overrides:
        cmd += ["--set", o]
    return cmd


def _start_mcu(vm: Any, cmd: list[str]) -> Any:
    """The MCU image runs on the host (qemu-system-arm, not nested in the VM's emulation); its UART0 is a local
    TCP server that the VM's second serial port joins: ttyS1 in the guest, where slcand attaches it."""
    from bench.mcu import McuImage

    mcu = McuImage()
    port = mcu.start()
    vm.qemu_opts.append(
        f"-chardev socket,id=slcan,host=127.0.0.1,port={port},nodelay=on -device isa-serial,chardev=slcan"
    )
    cmd += ["--drive", "mcu", "--drive-tty", GUEST_TTY]
    return mcu


def _raise_for(rc: int) -> None:
    """The capture's exit status as the host's error: a refused setting, a CAN link, any other failure."""
    if rc == CAPTURE_REFUSED:
        from bench.run.loop.configure import SettingRefused

        raise SettingRefused("a node refused a value of the scenario (the line above says which)")
    if rc == CAPTURE_LINK:
        from bench.canbus import LinkError

        raise LinkError("a CAN link in the VM could not be set up (the line above says why)")
    if rc != 0:
        raise RuntimeError(f"the capture inside the VM failed with status {rc}")


def vm_options(args: argparse.Namespace) -> Any:
    """The VM for this run's buses: vcanN are made in it; canN are emulated CAN controllers (Kvaser PCIcan,
    SJA1000) on one emulated bus, as many as the highest canN asks."""
    from bench.run.bus.vm import VmOptions

    interfaces, can_controllers = vm_links(tuple(dict.fromkeys(n for n in (args.bus, args.drive_bus) if n)))
    return VmOptions(
        timeout_s=3600,
        interfaces=interfaces,
        can_controllers=can_controllers,
        # --drive mcu: one vCPU. The image's frames cross can-gw between vcan0 and slcan0, and the guest kernel
        # queues a frame on the backlog of the CPU its sender runs on: with two vCPUs and a loaded host a
        # sender that moved between them had its frames reordered (the plant's currents after its sample: the
        # drive stepped on stale currents, EMCY 0xFF02 reasons 2 then 1; an image's trace frame after the
        # next SYNC). One vCPU keeps every frame in the order it was sent; the loop's rate is the serial
        # link's anyway (docs/BENCHMARKS.md).
        cpus=1 if getattr(args, "drive", "node") == "mcu" else VmOptions.cpus,
    )


class _Quiet:
    """The VM's console: only the guest command's own lines that matter reach the user."""

    def write(self, text: str) -> None:
        for line in text.splitlines():
            if line.startswith(("bench ", "Traceback", "RuntimeError", "  File", "Error", "error")):
                sys.stderr.write(line + "\n")

    def flush(self) -> None:
        sys.stderr.flush()


def capture_only(args: argparse.Namespace) -> int:
    """`bench capture` (run inside the VM): configure, run and record candump.log; no decoding
    (the host does it). Writes capture.json with the run's wall time."""
    from bench.run.options import run_options
    from bench.run.pipeline import capture_to_log

    try:
        sc = load(args.scenario, args.overrides)
    except ScenarioError as exc:
        print(f"bench capture: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    opts = run_options(args, args.out)
    from bench.canbus import LinkError
    from bench.run.loop.configure import SettingRefused

    try:
        run_wall, stopped, links = capture_to_log(sc, opts)
    except SettingRefused as exc:  # bad input: the host exits 2
        print(f"bench capture: {exc}", file=sys.stderr)
        return CAPTURE_REFUSED
    except LinkError as exc:
        print(f"bench capture: {exc}", file=sys.stderr)
        return CAPTURE_LINK
    except Exception as exc:  # noqa: BLE001 - one line the host shows (the VM's console is filtered)
        print(f"bench capture: FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    (args.out / "capture.json").write_text(
        json.dumps({"run_wall_s": run_wall, "pid": os.getpid(), "stopped": stopped, "links": links})
    )
    if stopped:
        print(f"bench capture: stopped: {stopped['message']}")
    else:
        print(f"bench capture: {sc.periods} periods in {run_wall:.2f} s")
    return 0
