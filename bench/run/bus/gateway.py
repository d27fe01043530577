"""The fault injector between two SocketCAN buses: build/bin/fault_gateway (protocols/faults), side a
the plant's bus (plant, master, recorder), side b the drive's. The same injector code as direct mode's
in-process bus, so a scenario's [[faults]] hit the same frames at the same periods on both."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from bench.paths import binary
from bench.run.bus.nodes import end_process

LOG_NAME = "fault_gateway.log"  # the injector's actions, one a line (written when the gateway stops)

# the injector's actions as protocols/faults numbers them in its log (fi_kind_t, protocols/faults/fault_injector.h)
KINDS = ("pass", "drop", "delay", "duplicate", "corrupt", "reorder", "freeze", "thaw", "kill", "reset", "release")


class FaultGateway:
    def __init__(self, rules: str, side_a: str, side_b: str, out: Path, pids: dict[str, int], box: Any = None) -> None:
        self.box = box  # a CAN box lease: the gateway runs in the box, its files in the lease's stage
        out = box.stage if box is not None else out
        self.rules_path = out / "fault_rules.txt"
        self.log_path = out / LOG_NAME
        self.out_path = out / "fault_gateway.out"
        self.rules_path.write_text(rules)
        self.argv = [
            str(binary("fault_gateway")),
            *("--a", side_a, "--b", side_b, "--rules", str(self.rules_path), "--log", str(self.log_path)),
        ]
        for side, name in (("a", "plant"), ("b", "drive")):
            if name in pids:
                self.argv += [f"--pid-{side}", str(pids[name])]
        self.proc: Any = None  # subprocess.Popen or boxproc.BoxPopen
        self._fh: Any = None

    def start(self, timeout_s: float = 10.0) -> FaultGateway:
        self.log_path.unlink(missing_ok=True)
        if self.box is not None:
            self.proc = self.box.popen(self.argv, self.out_path)
        else:
            self._fh = open(self.out_path, "wb")  # noqa: SIM115 - closed in stop()
            self.proc = subprocess.Popen(self.argv, stdout=self._fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:  # it says so once both sockets are bound
            if self.out_path.exists() and b"rule(s)" in self.out_path.read_bytes():
                return self
            if self.proc.poll() is not None:
                break
            time.sleep(0.01)
        self.stop()
        raise RuntimeError(f"fault_gateway did not start: {self.out_path.read_text(errors='replace').strip()}")

    def stop(self) -> int | None:
        if self.proc is None:
            return None
        rc = end_process(self.proc, self._fh, 5.0)
        self.proc = None
        return rc

    def events(self) -> tuple[list[tuple[Any, ...]], int]:
        return read_log(self.log_path)


def read_log(path: Path) -> tuple[list[tuple[Any, ...]], int]:
    """The gateway's log: (period, t_us, rule, kind, side, cob_id, data) per action, and the actions it could
    not keep."""
    events: list[tuple[Any, ...]] = []
    lost = 0
    if not path.exists():  # the gateway died or was killed before writing it: nothing is known
        print(f"bench: {path} is missing: the fault gateway's actions are unknown", file=sys.stderr)
        return events, -1
    for line in path.read_text().splitlines():
        if line.startswith("# frames_in"):
            f = line.split()
            vals = dict(zip(f[1::2], f[2::2], strict=False))
            lost = sum(int(vals.get(k, 0)) for k in ("log_overflow", "held_overflow", "send_errors"))
            continue
        if not line or line.startswith("#"):
            continue
        period, t_us, rule, kind, side, cob, dlc, data = line.split()
        events.append(
            (
                int(period),
                int(t_us),
                int(rule),
                KINDS.index(kind),
                0 if side == "a" else 1,
                int(cob, 16),
                bytes.fromhex(data)[: int(dlc)],
            )
        )
    return events, lost
