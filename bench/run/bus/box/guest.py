"""The CAN box's guest side: the shell script virtme-ng runs in the VM once, for the box's whole life.

It loads the kernel's CAN modules, attaches every bridge port (a virtio console, /dev/hvcN, which QEMU joins
to a TCP socket on the host) to the kernel's SLCAN line discipline with can-utils' slcand, and then serves the
control channel (the virtio port box.control): one request a line, `SEQ VERB ARG`; the answer `SEQ RC N` and
the N lines of the output (stdout and stderr).

Only what needs the kernel lives here: links, node processes, candump, the fault gateway, can-gw routes. The
agent is bash (no Python in the guest: it starts in ~15 s there and runs ~50x slower); a request is one
command line the host wrote (bench/run/bus/box/lease.py), run in a subshell of the agent (a fork, no exec:
each exec costs tens of milliseconds under TCG), so the agent itself stays small.
"""

from __future__ import annotations

import shlex
from pathlib import Path

from bench.run.bus.box.life import BOX_CPUS

# Verbs of the control channel (bench/run/bus/box/control.py sends them):
#   sh LINE    run the command line (one line) in a subshell, answer its status and output (stdout+stderr)
#   ping -     answer 0 and the guest's uptime
#   down -     answer 0, then stop every process and power the guest off
AGENT = r"""
ctl=
for ((k = 0; k < 100; k++)); do
  for d in /sys/class/virtio-ports/*; do
    n=; read -r n <"$d/name" 2>/dev/null; [ "$n" = box.control ] && ctl=/dev/${d##*/}
  done
  [ -n "$ctl" ] && [ -e "$ctl" ] && break; sleep 0.05
done
[ -n "$ctl" ] || fail "no control port (box.control)"
exec 3<>"$ctl"
mkfifo /run/box/nap && exec 4<>/run/box/nap
out=/run/box/out
running=1
while [ $running = 1 ]; do
  # a virtio port reads end-of-file while no host is connected: nap (a read of an empty fifo, no fork)
  if ! IFS=' ' read -r -u 3 seq verb arg; then read -r -t 0.02 -u 4 _; continue; fi
  seq=${seq//[^0-9]/}
  [ -n "$seq" ] || continue
  case "$verb" in
    sh) ( eval "$arg" ) >"$out" 2>&1 </dev/null; rc=$? ;;
    ping) read -r up _ </proc/uptime; printf '%s\n' "$up" >"$out"; rc=0 ;;
    down) : >"$out"; rc=0; running=0 ;;
    *) printf 'unknown verb %s\n' "$verb" >"$out"; rc=127 ;;
  esac
  mapfile -t lines <"$out"
  printf '%s %s %s\n' "$seq" "$rc" "${#lines[@]}" >&3
  [ ${#lines[@]} = 0 ] || printf '%s\n' "${lines[@]}" >&3
done
"""


HOLDER = "/run/box/holder-"  # + the namespace: the PID of its holder process (_slot_lines)
LAUNCHER = "/run/box/launch-"  # + the namespace: its launcher's fifo, + ".pid": the launcher's PID (_slot_lines)


def _slot_lines(slots: int, master_ids: list[tuple[int, int]]) -> list[str]:
    """Each slot's namespace b<s>, made once at boot (under TCG each program started costs tens of
    milliseconds: a run then starts none to get its buses): vcan0 and vcan1 (the fault gateway's drive side),
    its two bridge ports, and the can-gw routes - the tap sends every frame to vcan0 (and sees every frame of it
    once the taps are on: life.set_taps; each frame routed to a tap costs the guest the SLCAN encoding and the
    console's write, whether a host listens or not: the lockstep loop ran 2.5-3.4x slower with it), the master's
    port sends every frame and sees `master_ids` only ((identifier, mask); python-can's SLCAN reader takes a byte
    at a time, the PDO stream stays in the box where candump records it). QEMU drops what is routed to a port no
    host has connected: a master that connects later sees no old frame. A holder process sleeps in each
    namespace for the box's life: /proc/HOLDER/root/sys/class/net is the namespace's own sysfs, read by the
    agent's builtins (Lease.link_infos: ~30 ms, where an `ip` exec costs 270-520 ms under TCG). A launcher, a bash
    in the namespace on the slot's vCPU, reads command lines from its fifo and runs each in the background: a
    process it starts is in the slot and on its vCPU with one exec, its own (Lease.popen; `ip netns exec` and
    `taskset` before it cost ~145 ms of the guest's time a process under TCG)."""
    rules = ["cangw -A -s $t -d vcan0 -e", "cangw -A -s $m -d vcan0 -e"]
    rules += [f"cangw -A -s vcan0 -d $m -e -f {c:03X}:{k:03X}" for c, k in master_ids]
    batch = "\\n".join(
        ["link set lo up"]
        # MTU 72: the links carry CAN FD frames too (a scenario's frames.can = "fd"), and classic ones as before
        + [f"link add {v} type vcan\\nlink set {v} mtu 72 txqueuelen 4000 up" for v in ("vcan0", "vcan1")]
        + ["link set $m txqueuelen 1000 up", "link set $t txqueuelen 1000 up"]
    )
    moves = "\\n".join(
        f"netns add b{s}\\nlink set bslc{2 * s - 1} netns b{s}\\nlink set bslc{2 * s} netns b{s}"
        for s in range(1, slots + 1)
    )
    return [
        f'printf "{moves}\\n" | ip -batch - || fail "the slots\' namespaces"',
        f"for ((s = 1; s <= {slots}; s++)); do",  # the slots at once: their execs overlap on the guest's CPUs
        "  ( m=bslc$((2 * s - 1)); t=bslc$((2 * s)); ns=b$s",
        f'  printf "{batch}\\n" | ip -n $ns -batch - || fail "slot $s links"',
        f'  ip netns exec $ns bash -c "{" && ".join(rules)}" || fail "slot $s routes"',
        f"  ip netns exec $ns sleep infinity </dev/null >/dev/null 2>&1 & echo $! >{HOLDER}$ns",
        f'  mkfifo {LAUNCHER}$ns || fail "slot $s launcher"',
        f"  ip netns exec $ns taskset -c $(((s - 1) % {BOX_CPUS})) bash -c "
        + shlex.quote('exec 6<>"$1"; while IFS= read -r -u 6 c; do eval "$c"; done')
        + f" launcher {LAUNCHER}$ns </dev/null >/dev/null 2>&1 & echo $! >{LAUNCHER}$ns.pid ) &",
        "done",
        "wait",
    ]


def guest_script(state_dir: Path, ports: int, env_lines: list[str], master_ids: list[tuple[int, int]]) -> str:
    """The job script: modules, the bridge ports hvc0 .. hvc<ports-1> as SLCAN links bslc1 .. bslc<ports>, two
    a slot in its namespace (_slot_lines), a ready mark in `state_dir`, the control loop, and power-off when it
    ends (`down`, or the host closing the box)."""
    ready = shlex.quote(str(state_dir / "ready"))
    failed = shlex.quote(str(state_dir / "guest.failed"))
    lines = [
        "#!/bin/bash",
        "set -u",
        *env_lines,
        f"rm -f {ready}",
        "mkdir -p /run/box /run/netns",
        "mkfifo /run/box/boot.nap && exec 5<>/run/box/boot.nap",  # a nap without a fork (read -t of a fifo)
        'fail() { echo "$1" > ' + failed + "; sync; (poweroff -f || echo o > /proc/sysrq-trigger) >/dev/null 2>&1; }",
        "modprobe -a vcan can_raw can_bcm slcan can-gw || fail 'modprobe vcan can_raw can_bcm slcan can-gw failed'",
        f"for ((i = 1; i <= {ports}; i++)); do",  # the ports at once (each a few execs under TCG)
        '  ( t=/dev/hvc$((i - 1)); for ((k = 0; k < 100; k++)); do [ -e "$t" ] && break; read -r -t 0.05 -u 5 _; done',
        '  stty -F "$t" raw -echo || fail "no $t (the bridge ports did not appear)"',
        '  slcand -o -c -s8 "$t" bslc$i || fail "slcand on $t failed" ) &',
        "done",
        "wait",
        # each link up in its slot's namespace (a link moved there is down: _slot_lines)
        f"for ((i = 1; i <= {ports}; i++)); do",
        "  for ((k = 0; k < 100; k++)); do [ -e /sys/class/net/bslc$i ] && break; read -r -t 0.05 -u 5 _; done",
        '  [ -e /sys/class/net/bslc$i ] || fail "bslc$i did not appear"',
        "done",
        *_slot_lines(ports // 2, master_ids),
        f"echo ready > {ready}; sync",
        AGENT.strip("\n"),
        # the end: every process of every run, then the guest
        "for ns in $(ip netns list | cut -d' ' -f1); do ip netns pids \"$ns\" | xargs -r kill -9; done",
        "pkill -9 slcand; sync",
        "(poweroff -f || echo o > /proc/sysrq-trigger) >/dev/null 2>&1",
        "",
    ]
    return "\n".join(lines)
