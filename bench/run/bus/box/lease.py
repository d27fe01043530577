"""A run's share of the CAN box: a slot (a lock file on the host, held while the run runs), its own buses in a
network namespace of the guest (the vcan links the run names, `vcan0` and with faults `vcan1`: two runs at
once never share a bus and keep the same names and node-IDs), the slot's two bridge ports in that namespace
(the master's, routed by can-gw filtered to what the master listens to; a tap with every frame, for a user's
python-can script), a staging folder shared with the guest for the processes' output and candump's log, and
the processes it started there (boxproc.BoxPopen: a subprocess.Popen's face for a process in the guest)."""

from __future__ import annotations

import fcntl
import json
import os
import shlex
import shutil
import time
import uuid
from pathlib import Path
from typing import IO, Any

from bench.run.bus.box import life
from bench.run.bus.box.boxproc import BoxPopen
from bench.run.bus.box.control import BoxError, BoxGone, Control
from bench.run.bus.box.guest import HOLDER, LAUNCHER

# a link's counters in sysfs (statistics/NAME) and their keys in canbus.link_info
LINK_STATS = ("rx_packets", "tx_packets", "rx_errors", "tx_errors", "rx_dropped", "tx_dropped")
LINK_KEYS = ("rx_frames", "tx_frames", "rx_errors", "tx_errors", "rx_dropped", "tx_dropped")


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
        self.started_unseen = False  # a process whose start was not seen (BoxPopen raised): the slot is not clean
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
        try:
            p = BoxPopen(self, argv, log, err, in_slot)
        except BoxError:  # not seen to start: it may still start late, so the slot is cleaned before its next run
            self.started_unseen = True
            raise
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
            _write_slot_meta(self.slot, {**_slot_meta(self.slot), "clean": not self.started_unseen})
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
