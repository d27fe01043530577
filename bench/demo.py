"""The README's main job. Until the control loop lands it proves the bus: two C
processes exchange and verify frames over a real vcan0 (host or VM)."""

from __future__ import annotations

import argparse
import sys

from .canbus import host_has_vcan
from .vm import VmError, VmOptions, run_in_vm


def main(args: argparse.Namespace) -> int:
    count = int(args.count)
    cmd = [sys.executable, "-m", "bench.cli", "pingpong", "--iface", "vcan0", "--count", str(count)]
    if host_has_vcan():
        print("demo: host kernel has SocketCAN; using vcan0 on the host")
        import subprocess

        rc = subprocess.call(cmd)
    else:
        print("demo: host kernel has no SocketCAN; booting the virtme-ng VM for a real vcan0 (about 20 s)")
        try:
            rc = run_in_vm(cmd, VmOptions(timeout_s=900))
        except VmError as exc:
            print(f"demo: {exc}", file=sys.stderr)
            return 69
    if rc == 0:
        print(f"demo: done: {count} frames went from a C 'ping' process to a C 'echo' process over vcan0 and "
              f"back, every answer verified byte by byte (round-trip statistics above)")
    else:
        print(f"demo: FAILED with status {rc}", file=sys.stderr)
    return rc
