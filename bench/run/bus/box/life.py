"""The CAN box's life cycle on the host: `up` (boot once, or find it running), `status`, `down`, and the keeper
process that holds the VM (virtme-ng/QEMU) for the box's life and powers it off after an idle time.

State lives in STATE/box (shared with the guest): state.json (the keeper's PID, the ports, the idle timeout),
`ready` (written by the guest once its links are up), console.log (the VM's console), one lock file per slot
(a run holds its slot's lock while it runs: bench/run/bus/box/lease.py), `last_use` (its time stamp is the
last lease's), exit.json (how the last box ended)."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from typing import Any

from bench.paths import STATE
from bench.run.bus.box.control import BoxError, BoxGone, Control, pid_alive

BOX_DIR = STATE / "box"
STOPPING = "stopping.json"  # written by the keeper while it powers the box off
BOX_CPUS = 2  # the box's vCPUs (keeper.py boots it so); each slot's processes run on one of them (lease.in_ns)
TAPS = "taps.on"  # present while the taps see their slots' vcan0 (set_taps)
OWNER_ENV = "BENCH_BOX_OWNER"  # recorded in the state of a box this process boots (BoxInfo.booted_by)
DEFAULT_IDLE_S = 600.0  # a box nobody used for this long powers off (bench box up --idle-timeout, BENCH_BOX_IDLE_S)
DEFAULT_SLOTS = 4  # runs the box carries at once (each: its own buses in a network namespace, 2 bridge ports;
# the guest's hvc driver has 8 consoles: at most 4)
# What each slot's bridge port routes to the master ((identifier, mask)): SDO answers and heartbeats, as the
# kernel filters of a master on a host bus; the run adds its hold announcement (Lease.add_master_ids).
MASTER_IDS = [(0x580, 0x780), (0x700, 0x780)]
BOOT_WAIT_S = 300.0  # a loaded 2-core host boots the TCG guest in 13-60 s


@dataclass
class BoxInfo:
    keeper_pid: int
    control_port: int
    ports: list[int]  # bridge ports: 2 per slot (the master's, a tap's), in slot order
    slots: int
    started: float
    idle_timeout_s: float
    booted_s: float | None
    # who booted it: BENCH_BOX_OWNER of the booting process (a pytest session's token: the session stops only a
    # box it booted, never one another session or a user started while it ran), or None
    booted_by: str | None = None
    # the accelerator: asked for (auto, kvm, tcg: accel.choice), what runs ("kvm" or "tcg"; "kvm?" while the keeper
    # tries KVM) and why (accel.Plan.why, or the failure of a KVM attempt)
    accel_asked: str = "auto"
    accel: str = "tcg"
    accel_why: str = ""

    @property
    def control(self) -> Control:
        return Control(self.control_port, BOX_DIR / "control.lock")

    def master_port(self, slot: int) -> int:
        return self.ports[2 * (slot - 1)]

    def tap_port(self, slot: int) -> int:
        return self.ports[2 * (slot - 1) + 1]


def channel(port: int) -> str:
    """python-can's channel of a bridge port (interface "slcan": pyserial's socket:// URL)."""
    return f"socket://127.0.0.1:{port}"


def read_info() -> BoxInfo | None:
    """The running box, or None (no state, or its keeper is gone: the state is stale and removed)."""
    path = BOX_DIR / "state.json"
    try:
        raw = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    known = {f.name for f in dataclasses.fields(BoxInfo)}  # a later bench's state may hold more
    info = BoxInfo(**{k: v for k, v in raw.items() if k in known})
    if not pid_alive(info.keeper_pid):
        path.unlink(missing_ok=True)
        return None
    return info


def slots_held_by_others(info: BoxInfo, owner: str | None = None) -> bool:
    """Whether a slot of the box is held by a process other than this one (its run's slot-N.json names it) and,
    given `owner` (a session's BENCH_BOX_OWNER), not by a run of that session either: a cancelled pytest session
    stops the box it booted even while one of its own runs is still giving its slot back."""
    for slot in range(1, info.slots + 1):
        if not slot_held(slot):
            continue
        try:
            meta = json.loads((BOX_DIR / f"slot-{slot}.json").read_text())
        except (OSError, ValueError):
            return True
        if meta.get("pid") != os.getpid() and (owner is None or meta.get("owner") != owner):
            return True
    return False


def is_ready() -> bool:
    return (BOX_DIR / "ready").exists()


def touch_use() -> None:
    BOX_DIR.mkdir(parents=True, exist_ok=True)
    (BOX_DIR / "last_use").touch()


def idle_timeout_default() -> float:
    env = os.environ.get("BENCH_BOX_IDLE_S")
    return float(env) if env else DEFAULT_IDLE_S


def up(
    idle_timeout_s: float | None = None, slots: int = DEFAULT_SLOTS, say: Any = None, accel: str | None = None
) -> BoxInfo:
    """The running box, booted now if there is none (waits until its links are up). `say` prints progress; `accel`
    (auto, kvm, tcg; default BENCH_BOX_ACCEL or auto) chooses the accelerator of a box booted now (bench/run/bus/box/
    accel.py). A KVM attempt that failed is said in one line."""
    import fcntl

    from bench.run.bus.box import accel as accel_mod

    asked = accel_mod.choice(accel)
    accel_mod.deadline_s()  # a bad BENCH_BOX_KVM_DEADLINE_S refused here, not in the keeper with its VM started
    say = say or (lambda text: print(text, file=sys.stderr, flush=True))
    BOX_DIR.mkdir(parents=True, exist_ok=True)
    with open(BOX_DIR / "up.lock", "a+b") as lock:  # one boot at a time; the others wait for it
        fcntl.flock(lock, fcntl.LOCK_EX)
        info = read_info()
        if info is None:
            wait_stopped()  # a box powering off (idle, down) ends before the next boots
            idle = idle_timeout_default() if idle_timeout_s is None else idle_timeout_s
            say(
                "bench: starting the CAN box (a VM with the kernel's vcan; this host's kernel has no SocketCAN): "
                f"boot ~15-60 s, once; it powers off after {idle:g} s unused (bench box down stops it now)"
            )
            info, proc = _start_keeper(idle, slots, asked)
        else:
            proc = None
        t0 = time.monotonic()
        while not is_ready():
            if (proc is not None and proc.poll() is not None) or not pid_alive(info.keeper_pid):
                raise BoxError(f"the CAN box failed to start: {_why_ended()}")
            if time.monotonic() - t0 > BOOT_WAIT_S:
                down()
                raise BoxError(f"the CAN box did not come up within {BOOT_WAIT_S:.0f} s (see {BOX_DIR}/console.log)")
            time.sleep(0.2)
    now = read_info() or info
    settle = time.monotonic() + 1.0  # the keeper writes booted_s within 0.5 s of the guest's ready mark
    while proc is not None and now.booted_s is None and time.monotonic() < settle:
        time.sleep(0.05)
        now = read_info() or now
    if proc is not None and now.accel == "tcg" and now.accel_why.startswith(accel_mod.FAILED):
        say(f"bench: the CAN box runs on TCG (emulation): {now.accel_why}")
    return now


def next_accel() -> tuple[bool, str]:
    """Whether the next boot tries KVM, and why (or why not): bench/run/bus/box/accel.py. ValueError for a bad
    BENCH_BOX_ACCEL."""
    from bench.run.bus.box import accel

    plan = accel.plan(BOX_DIR, accel.choice())
    return plan.try_kvm, plan.why


def _start_keeper(idle_s: float, slots: int, accel: str) -> tuple[BoxInfo, subprocess.Popen[bytes]]:
    for name in ("ready", "guest.failed", "exit.json", "state.json", TAPS):
        (BOX_DIR / name).unlink(missing_ok=True)
    for old in BOX_DIR.glob("slot-*.state"):  # the last box's namespaces are gone with it
        old.unlink()
    ports = free_ports(1 + 2 * slots)
    info = BoxInfo(
        keeper_pid=0,
        control_port=ports[0],
        ports=ports[1:],
        slots=slots,
        started=time.time(),
        idle_timeout_s=idle_s,
        booted_s=None,
        booted_by=os.environ.get(OWNER_ENV) or None,
        accel_asked=accel,
    )
    log = open(BOX_DIR / "keeper.log", "wb")  # noqa: SIM115 - the keeper's own; closed here once started
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench.run.bus.box.keeper", json.dumps(info.__dict__)],
        stdin=subprocess.DEVNULL,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,  # not the terminal's: a run's Ctrl-C must leave the box up
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    log.close()
    info.keeper_pid = proc.pid
    t0 = time.monotonic()
    while not (BOX_DIR / "state.json").exists():  # the keeper writes it once QEMU is started
        if proc.poll() is not None:
            raise BoxError(f"the CAN box failed to start: {_why_ended()}")
        if time.monotonic() - t0 > 60:
            break
        time.sleep(0.05)
    return info, proc


def _why_ended() -> str:
    for name in ("guest.failed", "exit.json"):
        p = BOX_DIR / name
        if p.exists():
            return p.read_text().strip()
    log = BOX_DIR / "keeper.log"
    tail = log.read_text(errors="replace").strip().splitlines()[-5:] if log.exists() else []
    return " | ".join(tail) or f"no reason recorded (see {BOX_DIR}/console.log)"


def free_ports(n: int) -> list[int]:
    """n TCP ports of 127.0.0.1 free now (QEMU binds them a moment later)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket()
            s.bind(("127.0.0.1", 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def down(timeout_s: float = 60.0) -> bool:
    """Stop the box (its runs' processes, the guest, QEMU, the keeper). False when none was running."""
    info = read_info()
    if info is None:
        going = stopping() is not None
        wait_stopped(timeout_s)  # one powering off by itself (idle): its end awaited, so no QEMU is left
        return going
    try:
        os.kill(info.keeper_pid, signal.SIGTERM)  # the keeper powers the guest off, then ends QEMU
    except ProcessLookupError:
        return False
    deadline = time.monotonic() + timeout_s
    while pid_alive(info.keeper_pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    try:
        os.killpg(info.keeper_pid, signal.SIGKILL)  # whatever is left of its group (QEMU included)
    except (ProcessLookupError, PermissionError):
        pass
    (BOX_DIR / "state.json").unlink(missing_ok=True)
    return True


def taps_on() -> bool:
    """Whether the running box's taps see their slot's vcan0 (bench box tap on|off; off when a box boots)."""
    return (BOX_DIR / TAPS).exists()


def tap_rule(slot: int, on: bool) -> str:
    """The command line that routes (or stops routing) a slot's vcan0 to its tap."""
    return f"ip netns exec b{slot} cangw -{'A' if on else 'D'} -s vcan0 -d bslc{2 * slot} -e" + (
        "" if on else " ; true"
    )


def set_taps(on: bool) -> BoxInfo:
    """Every slot's tap on (it sees every frame of the slot's vcan0: a user's python-can script, can.viewer) or
    off (the default: a tap costs the guest each frame's SLCAN encoding, the loop runs ~3x faster without)."""
    info = read_info()
    if info is None or not is_ready():
        raise BoxError("no CAN box is up (bench box up)")
    if on != taps_on():
        info.control.check(" && ".join(tap_rule(s, on) for s in range(1, info.slots + 1)), "switching the taps")
        (BOX_DIR / TAPS).touch() if on else (BOX_DIR / TAPS).unlink(missing_ok=True)
    return info


def stopping() -> dict[str, Any] | None:
    """The keeper of a box that is powering off ({"keeper_pid", "why"}), or None."""
    try:
        rec: dict[str, Any] = json.loads((BOX_DIR / STOPPING).read_text())
    except (OSError, ValueError):
        return None
    return rec if pid_alive(int(rec.get("keeper_pid", 0))) else None


def wait_stopped(timeout_s: float = 60.0) -> None:
    """Until a box that is powering off has ended (its keeper gone: QEMU with it), at most `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while (rec := stopping()) is not None and time.monotonic() < deadline:
        time.sleep(0.1)
    if rec is not None:
        try:
            os.killpg(int(rec["keeper_pid"]), signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


def status() -> dict[str, Any]:
    """What `bench box status` prints: state, uptime, idle timeout, runs and their bridge channels."""
    info = read_info()
    if info is None and (going := stopping()) is not None:
        return {"state": "stopping", "keeper_pid": going["keeper_pid"], "why": going["why"]}
    if info is None:
        last = BOX_DIR / "exit.json"
        return {"state": "down", "last_end": json.loads(last.read_text()) if last.exists() else None}
    out: dict[str, Any] = {
        "state": "up" if is_ready() else "booting",
        "keeper_pid": info.keeper_pid,
        "up_s": round(time.time() - info.started, 1),
        "booted_s": info.booted_s,
        "accel": info.accel,
        "accel_why": info.accel_why,
        "idle_timeout_s": info.idle_timeout_s,
        "control_port": info.control_port,
        "taps": taps_on(),
        "slots": [],
    }
    try:
        out["idle_s"] = round(time.time() - (BOX_DIR / "last_use").stat().st_mtime, 1)
    except OSError:
        out["idle_s"] = None
    if out["state"] == "up":
        try:
            out["guest_uptime_s"] = info.control.ping()
        except BoxGone as exc:
            out["state"] = f"not answering ({exc})"
    for slot in range(1, info.slots + 1):
        rec: dict[str, Any] = {"slot": slot, "in_use": False}
        meta = BOX_DIR / f"slot-{slot}.json"
        if meta.exists() and slot_held(slot):
            rec.update(json.loads(meta.read_text()), in_use=True)
        rec["tap"] = {"interface": "slcan", "channel": channel(info.tap_port(slot))}
        out["slots"].append(rec)
    return out


def slot_held(slot: int) -> bool:
    """Whether a run holds the slot's lock now."""
    import fcntl

    path = BOX_DIR / f"slot-{slot}.lock"
    if not path.exists():
        return False
    with open(path, "a+b") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(fh, fcntl.LOCK_UN)
        return False
