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
from pathlib import Path

from bench.paths import REPO, STATE
from bench.root import INSTALLED
from bench.run.bus.box import accel
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
    (BOX_DIR / "console.log").write_bytes(b"")  # this box's: a KVM attempt's lines, then the boot's

    def command(kvm: bool) -> list[str]:
        opts = VmOptions(cpus=BOX_CPUS, timeout_s=0, qemu_opts=qemu_opts(info), kvm=kvm)
        cmd = _vng_argv(vng, kern[0], opts, {home}, job)
        cmd[-1] = f"bash {job}"
        return cmd

    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(vng.parent), env.get("PATH", "")])
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda s, f: stop.set())
    signal.signal(signal.SIGINT, lambda s, f: stop.set())
    t0 = time.monotonic()
    plan = accel.plan(BOX_DIR, info.accel_asked)
    info.accel_why = plan.why
    proc = _try_kvm(info, command(True), env, stop) if plan.try_kvm else None
    if proc is None and not stop.is_set():
        info.accel = "tcg"
        proc = _start_vm(info, command(False), env, [])
    why = "stopped (bench box down)"
    while proc is not None:
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
    if proc is not None:
        _power_off(info, proc)
    _ended(why)
    (BOX_DIR / TAPS).unlink(missing_ok=True)
    (BOX_DIR / STOPPING).unlink(missing_ok=True)
    return 0


def _start_vm(info: BoxInfo, cmd: list[str], env: dict[str, str], tail: list[str]) -> subprocess.Popen[bytes]:
    """virtme-ng started (QEMU reopens its stdout: a pipe, never a file, and an open stdin), its console copied to
    console.log (and its last lines to `tail`), state.json written."""
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env)
    (BOX_DIR / "state.json").write_text(json.dumps(info.__dict__))
    threading.Thread(target=_copy_console, args=(proc, tail), daemon=True).start()
    return proc


def _try_kvm(
    info: BoxInfo, cmd: list[str], env: dict[str, str], stop: threading.Event
) -> subprocess.Popen[bytes] | None:
    """The VM booted with KVM, or None: QEMU ended, or the guest did not raise its links within the deadline (the
    attempt is then stopped, the failure recorded in kvm.json and said in info.accel_why), or the box was stopped
    meanwhile."""
    info.accel = "kvm?"
    deadline_s = accel.deadline_s()  # read before QEMU starts (life.up has checked it)
    tail: list[str] = []
    proc = _start_vm(info, cmd, env, tail)
    t0 = time.monotonic()
    failed = None
    while not is_ready():
        if proc.poll() is not None:
            time.sleep(0.2)  # the console's last lines
            said = [line for line in tail if "error" in line.lower()] or tail or [f"QEMU ended ({proc.returncode})"]
            failed = f"QEMU ended: {said[-1].strip()}"
            break
        if stop.is_set() or time.monotonic() - t0 > deadline_s:
            failed = None if stop.is_set() else f"no guest within {deadline_s:g} s ({accel.DEADLINE_ENV})"
            _stop_tree(proc)
            break
        time.sleep(0.1)
    else:
        info.accel = "kvm"
        accel.forget_failure(BOX_DIR)
        (BOX_DIR / "state.json").write_text(json.dumps(info.__dict__))
        return proc
    for name in ("ready", "guest.failed"):  # what the attempt's guest may have written
        (BOX_DIR / name).unlink(missing_ok=True)
    if failed is not None:
        accel.record_failure(BOX_DIR, failed)
        info.accel_why = f"{accel.FAILED}: {failed}; the next boots use TCG (bench box up --accel kvm tries again)"
    return None


def _stop_tree(proc: subprocess.Popen[bytes]) -> None:
    """virtme-ng and what it started (its shell, virtme-run, virtiofsd, QEMU: children, not a group of their own)
    killed. Stopped first, parents before children, until a look finds no new one: a process still running while
    its parent is killed can fork a child the scan missed, which then outlives the attempt and can hold what the TCG
    boot after it needs (the CI once saw that boot end at once with status 255)."""
    stopped: list[int] = []
    while new := [pid for pid in _tree(proc.pid) if pid not in stopped]:
        for pid in new:  # top-down: a stopped process forks no more, and its children stay its children
            _signal(pid, signal.SIGSTOP)
            stopped.append(pid)
    for pid in stopped:
        _signal(pid, signal.SIGKILL)
    proc.wait()


def _tree(root: int) -> list[int]:
    """`root` and its descendants, parents first (from /proc)."""
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    tree, todo = [], [root]
    while todo:
        pid = todo.pop(0)
        tree.append(pid)
        todo += children.get(pid, [])
    return tree


def _signal(pid: int, sig: signal.Signals) -> None:
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass


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


def _copy_console(proc: subprocess.Popen[bytes], tail: list[str]) -> None:
    assert proc.stdout is not None
    with open(BOX_DIR / "console.log", "ab") as fh:  # a KVM attempt's lines stay before the TCG boot's
        for raw in iter(proc.stdout.readline, b""):
            fh.write(raw)
            fh.flush()
            tail[:] = [*tail[-19:], raw.decode(errors="replace")]


def _ended(why: str) -> None:
    (BOX_DIR / "exit.json").write_text(json.dumps({"why": why, "at": time.time()}))
    print(f"bench box: {why}", flush=True)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
