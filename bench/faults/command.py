"""`bench faults`: every fault check (bench/faults/checks.py) on a bus, a table and faults.json."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bench.faults.checks import CHECKS, run_checks
from bench.faults.scenario import base
from bench.paths import lost_in_vm
from bench.scenario import ScenarioError, add_set_argument, parse, unselected_law


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--bus",
        default="direct",
        help="direct (default: in-process, on simulated time) or a vcan channel where the host has SocketCAN "
        "(vcan0: the drive goes on vcan1, joined by the fault gateway; on a host without CAN: "
        "bench vm -- bench faults --bus vcan0)",
    )
    p.add_argument(
        "--only",
        default=None,
        metavar="CHECK,...",
        help=f"run only these checks: {', '.join(CHECKS)}",
    )
    add_set_argument(
        p,
        "change every check's scenario (You 2019's deadbeat on its motor, locked rotor, iq step 0 -> 1 A at "
        "period 20), as bench run --set does: another current law (--set controller.controller=pi; a law of "
        "your own with --law DIR) and its parameters (repeatable). How fast the loop recovers is judged against "
        "that law's own fault-free step",
    )
    p.add_argument("--out", type=Path, default=None, help="write faults.json here (a folder)")


def main(args: argparse.Namespace) -> int:
    only = [c.strip() for c in args.only.split(",")] if args.only else None
    bad = [c for c in only or [] if c not in CHECKS]
    if bad:
        print(f"bench faults: unknown check {bad[0]!r}; the checks: {', '.join(CHECKS)}", file=sys.stderr)
        return 2
    if args.out is not None and (lost := lost_in_vm(args.out)) is not None:
        print(f"bench faults: --out {lost}", file=sys.stderr)
        return 2
    from bench.run.bus.buses import choose_bus

    if not choose_bus(args.bus, box=False).in_process:
        from bench.canbus import probe_af_can

        if not probe_af_can().af_can:
            print(
                f"bench faults: --bus {args.bus}: this host's kernel has no SocketCAN; run it in the VM: "
                f"bench vm -- .venv/bin/bench faults --bus {args.bus}, or use --bus direct",
                file=sys.stderr,
            )
            return 2
    law = tuple(args.overrides)
    try:  # a bad key or value is refused before any run, naming the entry and its range
        sc = parse(base("fc-settings", law=law), "--set")
        if (unselected := unselected_law([sc], "the checks' scenario")) is not None:
            raise ScenarioError(unselected)
    except ScenarioError as exc:
        print(f"bench faults: {exc}", file=sys.stderr)
        return 2
    names = only or list(CHECKS)
    results = []
    t0 = time.monotonic()
    for i, name in enumerate(names, 1):
        print(f"[{i}/{len(names)}] {name} ...", end="", flush=True)
        t = time.monotonic()
        (c,) = run_checks(args.bus, [name], law)
        results.append(c)
        print(f" {'pass' if c.ok else 'FAIL'} ({time.monotonic() - t:.1f} s)", flush=True)
    print()
    for c in results:
        print(f"{'pass' if c.ok else 'FAIL':<5} {c.check_id:<24} {c.fault}")
        print(f"      expected: {c.expectation}")
        print(f"      measured: {', '.join(f'{k} {_fmt(v, k)}' for k, v in c.measured.items())}")
    failed = [c.check_id for c in results if not c.ok]
    print(
        f"\n{len(results) - len(failed)} of {len(results)} fault checks pass on bus {args.bus} "
        f"({time.monotonic() - t0:.1f} s)" + (f"; failed: {', '.join(failed)}" if failed else "")
    )
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        path = args.out / "faults.json"
        path.write_text(
            json.dumps(
                {"bus": args.bus, "set": list(law), "checks": [c.to_dict() for c in results]}, indent=2, default=str
            )
        )
        print(f"written: {path}")
    return 1 if failed else 0


def _fmt(v: object, key: str = "") -> str:
    if isinstance(v, float):
        return f"{v:.7g}" if key.endswith("_s") else f"{v:.4g}"
    if isinstance(v, list) and len(v) > 8:
        return f"[{', '.join(map(str, v[:8]))}, ... ({len(v)})]"
    return str(v)
