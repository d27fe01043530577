"""The CAN box's keeper: a host process, in a session of its own, that boots the VM and holds it.

`python -m bench.run.bus.box.keeper INFO_JSON` (started by life.up): writes the guest's job, starts virtme-ng
with the bridge ports (one virtio-serial controller, a virtconsole per port, each joined to a TCP server socket
of 127.0.0.1), copies the VM's console to console.log, writes state.json, and ends the box when asked (SIGTERM:
`bench box down`), when the box was unused for its idle timeout (no slot held, `last_use` older), or when QEMU
ends by itself. Whatever way it ends, state.json is removed and exit.json says why."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

from bench.paths import REPO, STATE
from bench.root import INSTALLED
from bench.run.bus.box.control import BoxGone
from bench.run.bus.box.guest import guest_script
from bench.run.bus.box.life import (
    BOX_CPUS,
    BOX_DIR,
    MASTER_IDS,
    STOPPING,
    TAPS,
    BoxInfo,
    is_ready,
    slot_held,
    touch_use,
)
from bench.run.bus.vm import VmOptions, _check_path, _vng_argv, find_kernel, readiness, vng_path


def qemu_opts(info: BoxInfo) -> list[str]:
    """The virtio-serial controller, one virtconsole per bridge port (/dev/hvc0 .. hvc7 in the guest: a
    virtconsole is a tty, which slcand needs; the guest's hvc driver has 8) and the control channel as a
    virtserialport named box.control (a plain character device: no tty needed)."""
    opts = ["-device virtio-serial-pci,id=bvs"]
    sock = "server=on,wait=off,nodelay=on"
    for i, port in enumerate(info.ports):
        opts.append(
            f"-chardev socket,id=bc{i},host=127.0.0.1,port={port},{sock} -device virtconsole,bus=bvs.0,chardev=bc{i}"
        )
    opts.append(
        f"-chardev socket,id=bctl,host=127.0.0.1,port={info.control_port},{sock} "
        "-device virtserialport,bus=bvs.0,chardev=bctl,name=box.control"
    )
    return opts


def main(argv: list[str]) -> int:
    info = BoxInfo(**json.loads(argv[0]))
    info.keeper_pid = os.getpid()
    missing = [f"{what}: {fix}" for what, ok, fix in readiness() if not ok]
    if missing:
        _ended("the VM is not ready: " + "; ".join(missing))
        return 1
    kern, vng = find_kernel(), vng_path()
    assert kern is not None and vng is not None
    job = BOX_DIR / "job.sh"
    path = ["export PATH=/usr/local/sbin:/usr/sbin:/sbin:/usr/bin:/bin"]
    job.write_text(guest_script(BOX_DIR, len(info.ports), path, MASTER_IDS))
    home = _check_path(STATE if INSTALLED else REPO)
    opts = VmOptions(cpus=BOX_CPUS, timeout_s=0, qemu_opts=qemu_opts(info))
    cmd = _vng_argv(vng, kern[0], opts, {home}, job)
    cmd[-1] = f"bash {job}"
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(vng.parent), env.get("PATH", "")])
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda s, f: stop.set())
    signal.signal(signal.SIGINT, lambda s, f: stop.set())
    t0 = time.monotonic()
    # QEMU reopens its stdout: a pipe (never a file), and an open stdin
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env)
    (BOX_DIR / "state.json").write_text(json.dumps(info.__dict__))
    threading.Thread(target=_copy_console, args=(proc,), daemon=True).start()
    why = "stopped (bench box down)"
    while True:
        if stop.wait(0.5):
            break
        if proc.poll() is not None:
            why = f"the VM ended by itself (status {proc.returncode}; see {BOX_DIR / 'console.log'})"
            break
        if info.booted_s is None and is_ready():
            touch_use()  # the idle time counts from the box's readiness (or its last run)
            info.booted_s = round(time.monotonic() - t0, 1)
            (BOX_DIR / "state.json").write_text(json.dumps(info.__dict__))
        if _idle_for(info) > info.idle_timeout_s > 0:
            why = f"idle for {info.idle_timeout_s:g} s"
            break
    # no run starts on a box going down; `bench box status` says "stopping" until QEMU has ended
    (BOX_DIR / STOPPING).write_text(json.dumps({"keeper_pid": os.getpid(), "why": why}))
    (BOX_DIR / "ready").unlink(missing_ok=True)
    (BOX_DIR / "state.json").unlink(missing_ok=True)
    _power_off(info, proc)
    _ended(why)
    (BOX_DIR / TAPS).unlink(missing_ok=True)
    (BOX_DIR / STOPPING).unlink(missing_ok=True)
    return 0


def _idle_for(info: BoxInfo) -> float:
    """Seconds since the box was last used, 0 while a run holds a slot or before it is up."""
    if not is_ready() or any(slot_held(s) for s in range(1, info.slots + 1)):
        return 0.0
    try:
        return time.time() - (BOX_DIR / "last_use").stat().st_mtime
    except OSError:
        return time.time() - info.started


def _power_off(info: BoxInfo, proc: subprocess.Popen[bytes]) -> None:
    """`down` to the guest (it kills every run's processes and powers off), QEMU's end awaited; else killed."""
    if proc.poll() is None:
        try:
            info.control.request("down", timeout_s=10)
        except BoxGone:
            pass
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            pass
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    # QEMU may outlive vng (same process group as this keeper): end the group but this process
    try:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        os.killpg(os.getpgrp(), signal.SIGTERM)
    except ProcessLookupError:
        pass


def _copy_console(proc: subprocess.Popen[bytes]) -> None:
    assert proc.stdout is not None
    with open(BOX_DIR / "console.log", "wb") as fh:
        for raw in iter(proc.stdout.readline, b""):
            fh.write(raw)
            fh.flush()


def _ended(why: str) -> None:
    (BOX_DIR / "exit.json").write_text(json.dumps({"why": why, "at": time.time()}))
    print(f"bench box: {why}", flush=True)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
