"""A run's share of the CAN box: a slot (a lock file on the host, held while the run runs), its own buses in a
network namespace of the guest (the vcan links the run names, `vcan0` and with faults `vcan1`: two runs at
once never share a bus and keep the same names and node-IDs), the slot's two bridge ports in that namespace
(the master's, routed by can-gw filtered to what the master listens to; a tap with every frame, for a user's
python-can script), a staging folder shared with the guest for the processes' output and candump's log, and
the processes it started there (BoxPopen: a subprocess.Popen's face for a process in the guest)."""

from __future__ import annotations

import fcntl
import json
import os
import shlex
import shutil
import signal
import time
import uuid
from pathlib import Path
from typing import IO, Any

from bench.run.bus.box import life
from bench.run.bus.box.control import BoxError, BoxGone, Control
from bench.run.bus.box.guest import HOLDER, LAUNCHER

# a link's counters in sysfs (statistics/NAME) and their keys in canbus.link_info
LINK_STATS = ("rx_packets", "tx_packets", "rx_errors", "tx_errors", "rx_dropped", "tx_dropped")
LINK_KEYS = ("rx_frames", "tx_frames", "rx_errors", "tx_errors", "rx_dropped", "tx_dropped")


def await_file(test: str, ticks: int) -> str:
    """A guest command line that waits until `[ TEST ]` holds, at most `ticks` naps of 10 ms (a read of the
    agent's empty fifo: no fork, no exec)."""
    return f"for ((k = 0; k < {ticks}; k++)); do [ {test} ] && break; read -r -t 0.01 -u 4 _; done"


POLL_CACHE_S = 0.25  # a process's state asked of the guest at most this often (liveness looks every 0.1 s)


class Lease:
    def __init__(self, info: life.BoxInfo, slot: int, lock: IO[bytes], links: tuple[str, ...]) -> None:
        self.info = info
        self.slot = slot
        self._lock = lock
        self.links = links
        self.bus = links[0]  # the plant's, the master's and the recorder's (the tap's too)
        self.routed: list[tuple[Any, ...]] = []  # (bus, identifier, mask) routed to the master's port by the run
        self.ns = f"b{slot}"
        self.master_link = f"bslc{2 * slot - 1}"
        self.tap_link = f"bslc{2 * slot}"
        self.ctl: Control = info.control
        self.stage = life.BOX_DIR / "runs" / f"{slot}-{uuid.uuid4().hex[:8]}"
        self.procs: list[BoxPopen] = []
        self.closed = False
        self._tap_opened = False

    # ---------------------------------------------------------------- channels
    @property
    def master_channel(self) -> str:
        return life.channel(self.info.master_port(self.slot))

    @property
    def tap_channel(self) -> str:
        return life.channel(self.info.tap_port(self.slot))

    def in_ns(self, argv: list[str]) -> str:
        """A command line that runs `argv` in the slot's namespace, on the slot's one vCPU of the box (life.BOX_CPUS).
        vcan queues a frame on the backlog of the CPU its sender runs on: a sender that moved between the guest's
        CPUs between two frames had them delivered in the other order (soak 3 of issue 52: the plant's 0x190 and
        0x290 of one period, the drive's EMCY 0xFF02), which no real bus does to one node's frames. One more exec
        (taskset) per process."""
        cpu = (self.slot - 1) % life.BOX_CPUS
        return f"ip netns exec {self.ns} taskset -c {cpu} " + " ".join(shlex.quote(a) for a in argv)

    # ---------------------------------------------------------------- set-up
    def _prepare(self) -> None:
        """The slot's namespace as a run needs it. Made at boot with vcan0, vcan1 and the routes (guest.py);
        a run that ended cleanly leaves nothing, so this asks nothing of the box then. After a run that died
        (SIGKILL, a crash) its processes are killed first; a vcan the run names that the slot lacks is made."""
        self.stage.mkdir(parents=True)
        meta = _slot_meta(self.slot)
        cmds = []
        if not meta.get("clean", True):
            keep = f'-e "$(<{HOLDER}{self.ns})" -e "$(<{LAUNCHER}{self.ns}.pid)"'  # the box's own, for its life
            cmds.append(f"ip netns pids {self.ns} | grep -vx {keep} | xargs -r kill -9; true")
        have = set(meta.get("links", ["vcan0", "vcan1"]))
        new = [v for v in self.links if v not in have]
        if new:
            batch = "\\n".join(f"link add {v} type vcan\\nlink set {v} mtu 72 txqueuelen 4000 up" for v in new)
            cmds.append(f"printf '{batch}\\n' | ip -n {self.ns} -batch -")
        self.routed = [tuple(x) for x in meta.get("routed", [])]
        if self.bus != "vcan0" and (self.bus, "tx") not in self.routed:  # the boot's routes are vcan0's
            m, t, b = self.master_link, self.tap_link, self.bus
            rules = [f"cangw -A -s {b} -d {t} -e", f"cangw -A -s {t} -d {b} -e", f"cangw -A -s {m} -d {b} -e"]
            rules += [f"cangw -A -s {b} -d {m} -e -f {c:03X}:{k:03X}" for c, k in life.MASTER_IDS]
            cmds.append(f"ip netns exec {self.ns} bash -c {shlex.quote(' && '.join(rules))}")
            self.routed += [(b, "tx"), *((b, c, k) for c, k in life.MASTER_IDS)]
        if cmds:
            self.ctl.check(" && ".join(f"{{ {c}; }}" for c in cmds), f"preparing the run's buses (slot {self.slot})")
        _write_slot_meta(self.slot, {**meta, "clean": False, "links": sorted(have | set(new)), "routed": self.routed})

    def add_master_ids(self, cob_ids: list[tuple[int, int]]) -> None:
        """Route these (identifier, mask) from the run's bus to the master's port too (kept for the slot's
        later runs: a route a run no longer needs only passes a few more frames)."""
        new = [x for x in cob_ids if (self.bus, *x) not in self.routed]
        if not new:
            return
        rules = [f"cangw -A -s {self.bus} -d {self.master_link} -e -f {c:03X}:{m:03X}" for c, m in new]
        self.ctl.check(
            f"ip netns exec {self.ns} bash -c {shlex.quote(' && '.join(rules))}", "routing the master's port"
        )
        self.routed += [(self.bus, *x) for x in new]
        _write_slot_meta(self.slot, {**_slot_meta(self.slot), "routed": self.routed})

    def open_tap(self) -> None:
        """This slot's tap sees its vcan0 while the lease is held (the taps may be off: life.set_taps)."""
        if not life.taps_on() and not self._tap_opened:
            self.ctl.check(life.tap_rule(self.slot, True), f"opening the tap of slot {self.slot}")
            self._tap_opened = True

    def link_infos(self, names: list[str]) -> dict[str, dict[str, Any] | None]:
        """canbus.link_info of each of the run's links (vcan links: the box makes no other), in one request: read
        from the namespace's own sysfs through its holder process (guest._slot_lines) by the agent's builtins; a
        box without a holder (booted by an older bench) answers `ip -json` as a host would."""
        stats = " ".join(LINK_STATS)
        script = (
            f"read -r h <{HOLDER}{self.ns} || exit 3; for n in {' '.join(names)}; do d=/proc/$h/root/sys/class/net/$n; "
            f'[ -e $d ] || {{ echo "$n -"; continue; }}; read -r f <$d/flags; read -r o <$d/operstate; '
            f'read -r u <$d/mtu; l="$n $f $o $u"; '
            f'for s in {stats}; do read -r v <$d/statistics/$s; l+=" $v"; done; echo "$l"; done'
        )
        try:
            rc, out = self.ctl.sh(script)
            if rc == 3:
                return self._link_infos_ip(names)
        except BoxGone:
            return dict.fromkeys(names)
        infos: dict[str, dict[str, Any] | None] = dict.fromkeys(names)
        for line in out.splitlines():
            parts = line.split()
            if len(parts) == 4 + len(LINK_STATS) and parts[0] in infos:
                flags, counts = int(parts[1], 16), [int(v) for v in parts[4:]]
                infos[parts[0]] = {
                    "kind": "vcan",
                    "up": bool(flags & 0x1),  # IFF_UP
                    "operstate": parts[2].upper(),  # as `ip -json` prints it
                    "mtu": int(parts[3]),  # 72: CAN FD frames too
                    **dict(zip(LINK_KEYS, counts, strict=True)),
                }
        return infos

    def _link_infos_ip(self, names: list[str]) -> dict[str, dict[str, Any] | None]:
        from bench.canbus import link_info_json

        try:
            rc, out = self.ctl.sh(f"ip -n {self.ns} -details -statistics -json link show")
        except BoxGone:
            return dict.fromkeys(names)
        try:
            links = {x.get("ifname"): x for x in json.loads(out)} if rc == 0 else {}
        except ValueError:
            links = {}
        return {n: link_info_json(json.dumps([links[n]])) if n in links else None for n in names}

    def gone(self) -> str | None:
        """Why the box no longer answers (its QEMU ended), or None while it does."""
        try:
            self.ctl.ping(timeout_s=5.0)
        except BoxGone as exc:
            return str(exc)
        return None

    # ---------------------------------------------------------------- processes
    def popen(self, argv: list[str], log: Path | None, err: Path | None = None, in_slot: bool = True) -> BoxPopen:
        """Start `argv` in the run's namespace, its output to `log` (under the stage: shared with the guest),
        its standard error there too or to `err`. in_slot=False: a helper that needs neither the slot's network
        namespace nor its vCPU (two execs fewer: ~0.2 s of the guest's time under TCG)."""
        p = BoxPopen(self, argv, log, err, in_slot)
        self.procs.append(p)
        return p

    # ---------------------------------------------------------------- end
    def close(self, keep: Path | None = None) -> None:
        """Kill what is left of the run's processes, give the slot back (clean: the next run asks nothing of the
        box), move the stage's files to `keep`."""
        if self.closed:
            return
        self.closed = True
        try:
            left = [p.pid for p in self.procs if p.returncode is None]
            if left:
                self.ctl.sh(f"kill -9 {' '.join(map(str, left))} 2>/dev/null; true", timeout_s=30)
            if self._tap_opened and not life.taps_on():
                self.ctl.sh(life.tap_rule(self.slot, False), timeout_s=30)
            _write_slot_meta(self.slot, {**_slot_meta(self.slot), "clean": True})
        except BoxGone:
            pass
        finally:
            if keep is not None:
                keep.mkdir(parents=True, exist_ok=True)
                for f in self.stage.iterdir():
                    shutil.move(str(f), keep / f.name)
            shutil.rmtree(self.stage, ignore_errors=True)
            (life.BOX_DIR / f"slot-{self.slot}.json").unlink(missing_ok=True)
            life.touch_use()
            fcntl.flock(self._lock, fcntl.LOCK_UN)
            self._lock.close()


def _slot_meta(slot: int) -> dict[str, Any]:
    """What the host knows of a slot's namespace in the running box (slot-N.state, removed with the box)."""
    try:
        return json.loads((life.BOX_DIR / f"slot-{slot}.state").read_text())  # type: ignore[no-any-return]
    except (OSError, ValueError):
        return {}


def _write_slot_meta(slot: int, meta: dict[str, Any]) -> None:
    (life.BOX_DIR / f"slot-{slot}.state").write_text(json.dumps(meta))


def acquire(links: tuple[str, ...], say: Any = None, wait_s: float = 3600.0) -> Lease:
    """A slot of the running box (booted now if none: life.up) for one run on `links` (vcanN names, the first
    the run's bus; its master's port gets life.MASTER_IDS and what add_master_ids adds); waits for a free slot."""
    info = life.up(say=say)
    t0, told = time.monotonic(), False
    while True:
        for slot in range(1, info.slots + 1):
            fh = open(life.BOX_DIR / f"slot-{slot}.lock", "a+b")  # noqa: SIM115 - held by the Lease
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                fh.close()
                continue
            life.touch_use()
            meta = {"pid": os.getpid(), "buses": list(links), "since": time.time(), "ns": f"b{slot}"}
            meta["owner"] = os.environ.get(life.OWNER_ENV)  # a pytest session's runs: life.slots_held_by_others
            (life.BOX_DIR / f"slot-{slot}.json").write_text(json.dumps(meta))
            lease = Lease(info, slot, fh, links)
            try:
                lease._prepare()
            except BaseException:
                lease.close()
                raise
            return lease
        if not told:
            (say or print)(f"bench: the CAN box's {info.slots} slots are in use; waiting for one")
            told = True
        if time.monotonic() - t0 > wait_s:
            raise BoxError(f"no slot of the CAN box came free within {wait_s:.0f} s")
        time.sleep(0.2)


class BoxPopen:
    """A process in the box, with the part of subprocess.Popen's face the bench uses (pid, poll, wait,
    send_signal, terminate, kill, returncode). Its exit status is written by a waiting shell in the guest."""

    def __init__(
        self, lease: Lease, argv: list[str], log: Path | None, err: Path | None = None, in_slot: bool = True
    ) -> None:
        self.lease = lease
        self.tag = uuid.uuid4().hex[:10]
        self.returncode: int | None = None
        self.gone: str | None = None  # why, when the box ended under the process
        self._asked = 0.0
        self._state: tuple[float, str | None] = (0.0, None)
        d = "/run/box"
        out = shlex.quote(str(log)) if log is not None else "/dev/null"
        err_to = "&1" if err is None else shlex.quote(str(err))
        plain = " ".join(shlex.quote(a) for a in argv)

        def wrapped(run: str) -> str:  # a subshell waits for the process and writes its exit status
            return (
                f"( {run} >{out} 2>{err_to} </dev/null & echo $! >{d}/{self.tag}.pid; wait $!; "
                f"echo $? >{d}/{self.tag}.exit ) >/dev/null 2>&1 </dev/null &"
            )

        # in the slot: through its launcher (guest._slot_lines) while it runs, else as a box booted by an older
        # bench does it (`ip netns exec`, `taskset`); outside it: a subshell of the agent's (a fork, no exec)
        start = wrapped(plain)
        if in_slot:
            f = f"{LAUNCHER}{lease.ns}"
            start = (
                f"if [ -p {f} ] && read -r lp <{f}.pid && [ -e /proc/$lp ]; then "
                f"printf '%s\\n' {shlex.quote(start)} >{f}; else {wrapped(lease.in_ns(argv))} fi;"
            )
        cmd = f"{start} {await_file(f'-s {d}/{self.tag}.pid', 500)}; read -r p <{d}/{self.tag}.pid && echo $p"
        out_text = lease.ctl.check(cmd, f"starting {Path(argv[0]).name}")
        self.pid = int(out_text.strip().splitlines()[-1])
        self.args = argv

    @property
    def exit_file(self) -> str:
        """The guest's file its exit status is written to once it has ended."""
        return f"/run/box/{self.tag}.exit"

    def _exit_now(self) -> int | None:
        rc, out = self.lease.ctl.sh(f"f=/run/box/{self.tag}.exit; [ -e $f ] && read -r x <$f && echo $x; true")
        return self.ended_with(out)

    def ended_with(self, text: str) -> int | None:
        """The exit status a guest command line read from exit_file (empty or '-': still running), kept as
        returncode, so that no further request asks it."""
        text = text.strip()
        if not text or text == "-":
            return None
        code = int(text)
        self.returncode = -(code - 128) if code > 128 else code  # a shell's 128+N: killed by signal N (Popen: -N)
        return self.returncode

    def exit_text(self) -> str:
        """A guest command line's word that expands to the exit status once it ended, else '-'."""
        f = self.exit_file
        return f"$([ -e {f} ] && read -r x <{f} && echo $x || echo -)"

    def poll(self, fresh: bool = False) -> int | None:
        """The exit status, None while it runs (asked of the guest at most every POLL_CACHE_S unless `fresh`)."""
        if self.returncode is not None:
            return self.returncode
        now = time.monotonic()
        if not fresh and now - self._asked < POLL_CACHE_S:
            return None
        self._asked = now
        try:
            self.returncode = self._exit_now()
        except BoxGone as exc:
            self.gone = str(exc)
            self.returncode = -signal.SIGKILL  # the box is gone, and the process with it
        return self.returncode

    def state(self) -> str | None:
        """The process's kernel state letter (/proc/PID/stat in the guest): T when stopped (asked at most every
        POLL_CACHE_S)."""
        now = time.monotonic()
        if now - self._state[0] < POLL_CACHE_S:
            return self._state[1]
        try:
            rc, out = self.lease.ctl.sh(f'read -r l </proc/{self.pid}/stat && echo "$l"')
            state = out.rsplit(")", 1)[1].split()[0] if rc == 0 else None
        except (IndexError, BoxGone):
            state = None
        self._state = (now, state)
        return state

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            try:
                self.lease.ctl.sh(f"kill -{int(sig)} {self.pid} 2>/dev/null; true")
            except BoxGone as exc:  # the box ended, and the process with it
                self.gone = str(exc)
                self.returncode = -signal.SIGKILL

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def end(self, timeout_s: float, wake: bool = False) -> int:
        """SIGTERM (and SIGCONT when `wake`), its exit awaited up to `timeout_s`, else SIGKILL: in one request
        (nodes.end_process; each request costs the guest tens of ms)."""
        end_all([self], timeout_s, wake)
        return self.returncode if self.returncode is not None else self.wait(timeout=30)

    def wait(self, timeout: float | None = None) -> int:
        """Its exit status, waited for in the guest (one request per 5 s, no polling from here)."""
        import subprocess

        deadline = None if timeout is None else time.monotonic() + timeout
        f = f"/run/box/{self.tag}.exit"
        while True:
            if self.returncode is not None:
                return self.returncode
            left = 5.0 if deadline is None else min(5.0, deadline - time.monotonic())
            if left <= 0:
                raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
            try:
                n = max(1, int(left * 100))
                self.lease.ctl.sh(await_file(f"-e {f}", n), timeout_s=left + 30)
            except BoxGone as exc:
                self.gone = str(exc)
                self.returncode = -signal.SIGKILL
            self.poll(fresh=True)


def end_all(procs: list[BoxPopen], timeout_s: float, wake: bool = False) -> None:
    """SIGTERM (and SIGCONT when `wake`: a frozen process gets its SIGTERM at once) to each of a lease's processes
    still running, their exits awaited up to `timeout_s` in all, SIGKILL to what is left, and every exit status,
    in one request (a run's nodes end together: Session.close)."""
    left = [p for p in procs if p.returncode is None]
    if not left:
        return
    pids = " ".join(str(p.pid) for p in left)
    cont = f"kill -18 {pids} 2>/dev/null; " if wake else ""
    ended = " -a ".join(f"-e {p.exit_file}" for p in left)
    killed = " ".join(
        f"[ -e {p.exit_file} ] || {{ kill -9 {p.pid} 2>/dev/null; {await_file(f'-e {p.exit_file}', 100)}; }};"
        for p in left
    )
    try:
        _, out = left[0].lease.ctl.sh(
            f"kill -15 {pids} 2>/dev/null; {cont}{await_file(ended, max(1, int(timeout_s * 100)))}; {killed} "
            f"echo {' '.join(p.exit_text() for p in left)}",
            timeout_s=timeout_s + 30,
        )
    except BoxGone as exc:
        for p in left:
            p.gone = str(exc)
            p.returncode = -signal.SIGKILL
        return
    words = out.split()[-len(left) :]
    for p, word in zip(left, words, strict=False):
        p.ended_with(word)
