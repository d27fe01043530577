"""`bench box up|status|down|tap on|off`: the CAN box, one VM booted once that carries the vcan buses of every run on a
host whose kernel has no CAN (bench/run/bus/box, docs/VM.md). Its arguments and its handler; its row of the
command table (bench/commands.py) names it and says what it is."""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any


def cmd_box(args: argparse.Namespace) -> int:
    from bench.run.bus.box import life
    from bench.run.bus.box.control import BoxError

    if args.action == "up":
        if args.idle_timeout is not None and args.idle_timeout < 0:
            print(f"bench box up: --idle-timeout = {args.idle_timeout:g}: seconds >= 0 (0: never)", file=sys.stderr)
            return 2
        if life.read_info() is not None and args.idle_timeout is not None:
            print("bench box up: the box is already up; its idle timeout stays (bench box down first)", file=sys.stderr)
        t0 = time.monotonic()
        try:
            info = life.up(args.idle_timeout, accel=args.accel)
        except (BoxError, ValueError) as exc:
            print(f"bench box up: {exc}", file=sys.stderr)
            return 1
        took = time.monotonic() - t0
        print(f"bench box: up (ready after {took:.1f} s; powers off after {info.idle_timeout_s:g} s unused)")
        return _print_status(life.status(), args.json)
    if args.action == "tap":
        if args.state is None:
            print("bench box tap: say on or off (bench box tap on)", file=sys.stderr)
            return 2
        try:
            life.set_taps(args.state == "on")
        except BoxError as exc:
            print(f"bench box tap: {exc}", file=sys.stderr)
            return 1
        print(f"bench box: taps {args.state}" + (" (each slot's tap sees its vcan0)" if args.state == "on" else ""))
        return 0
    if args.state is not None:
        print(f"bench box {args.action}: takes no {args.state!r} (only bench box tap on|off does)", file=sys.stderr)
        return 2
    if args.action == "down":
        print("bench box: stopped" if life.down() else "bench box: no box was running")
        return 0
    return _print_status(life.status(), args.json)


ACCEL_NAMES = {"kvm": "KVM", "tcg": "TCG (emulation)", "kvm?": "trying KVM"}


def _print_status(st: dict[str, Any], as_json: bool) -> int:
    if as_json:
        print(json.dumps(st, indent=2))
        return 0 if st["state"] == "up" else 3
    if st["state"] == "stopping":
        print(f"CAN box: stopping ({st['why']}; keeper PID {st['keeper_pid']})")
        return 3
    if st["state"] == "down":
        last = st.get("last_end")
        print("CAN box: down" + (f" (last: {last['why']})" if last else ""))
        return 3
    idle = st.get("idle_s")
    print(
        f"CAN box: {st['state']}, up {st['up_s']:.0f} s (booted in {st['booted_s'] or '?'} s), keeper PID "
        f"{st['keeper_pid']}, powers off after {st['idle_timeout_s']:g} s unused"
        + (f" (idle {idle:.0f} s)" if idle is not None else "")
    )
    print(f"accelerator: {ACCEL_NAMES.get(st['accel'], st['accel'])} ({st['accel_why']})")
    taps = "on" if st.get("taps") else "off (bench box tap on: a slot's tap then sees its vcan0)"
    print(f"taps: {taps}")
    print("slot  run                          tap: python-can can.Bus(interface=..., channel=...)")
    for s in st["slots"]:
        who = f"PID {s['pid']} on {', '.join(s['buses'])}" if s.get("in_use") else "free"
        print(f"{s['slot']:>4}  {who:<28} interface={s['tap']['interface']!r} channel={s['tap']['channel']!r}")
    print(
        "A slot's tap may send to its run's bus (vcan0 of that run) and, with the taps on, sees its every frame; runs "
        "get the free slots."
    )
    return 0 if st["state"] == "up" else 3


def box_arguments(b: argparse.ArgumentParser) -> None:
    b.add_argument(
        "action",
        choices=("up", "status", "down", "tap"),
        help="boot (or find) the box, show it, stop it; tap on|off: whether each slot's tap sees its run's vcan0 "
        "(off when the box boots: a tap costs the loop in the box ~3x its pace)",
    )
    b.add_argument("state", nargs="?", choices=("on", "off"), help="with tap: on or off")
    b.add_argument(
        "--idle-timeout",
        type=float,
        default=None,
        metavar="S",
        help="up: power off after S seconds without a run (default 600, or BENCH_BOX_IDLE_S; 0: never)",
    )
    b.add_argument(
        "--accel",
        choices=("auto", "kvm", "tcg"),
        default=None,
        help="up: the accelerator of a box booted now. auto (default, or BENCH_BOX_ACCEL): KVM when /dev/kvm is "
        "usable and KVM has not failed on this host before, else TCG; kvm: try KVM even if it failed before; tcg: "
        "never KVM. A KVM guest not up within 30 s (BENCH_BOX_KVM_DEADLINE_S) is stopped and the box boots on TCG, "
        "said in one line",
    )
    b.add_argument("--json", action="store_true", help="status as JSON (the tap channels of each slot)")
