"""One CiA 402 run: recorder, master set-up, the profile in real time, the way out, the results."""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path
from typing import Any

from bench.cia402 import NO_LOCKSTEP, cia402_bus
from bench.cia402.layout import Layout
from bench.cia402.master import DriveRefused, DriveStopped, Master
from bench.cia402.outcome import Interrupted, ignore_signals, raise_on_signals, summary_text, write_summary
from bench.cia402.plan import Frames, PlanError, Segment, bus_load, ignored_keys, targets
from bench.cia402.record import decode_log, states_passed, tracking, write_csv, write_plot
from bench.scenario import Scenario


def say(text: str) -> None:
    print(text, flush=True)


class Session:
    def __init__(
        self,
        args: argparse.Namespace,
        sc: Scenario,
        cycle_s: float,
        load: float,
        segs: list[Segment],
        eds: Path,
        out: Path,
    ) -> None:
        self.args, self.sc, self.cycle_s, self.load, self.segs, self.eds, self.out = (
            args,
            sc,
            cycle_s,
            load,
            segs,
            eds,
            out,
        )
        self.partial = out.with_name(out.name + ".partial")
        self.record_error: str | None = None  # the recorder's, when it could not write the whole log

    def run(self) -> int:
        if self.partial.exists():
            print(f"bench run: {self.partial} exists; remove it or choose another --out", file=sys.stderr)
            return 2
        self.partial.mkdir(parents=True)
        say(
            f"bench run: {self.sc.name}: CiA 402 master of drive 0x{self.args.drive_id:02X} on {self.args.bus}; "
            f"{NO_LOCKSTEP}; cycle {self.cycle_s * 1e3:g} ms ({len(self.segs)} target segments, "
            f"{self.sc.periods} cycles)"
        )
        raise_on_signals()
        recorder = self._recorder()
        master: Master | None = None
        layout: Layout | None = None
        code, reason = 1, "not started"
        try:
            master = Master(self.args.bus, self.args.interface, self.args.drive_id, self.eds, self.cycle_s)
            if isinstance(recorder, _SharedBusRecorder):
                recorder.attach(master.network)
            master.start_heartbeat()
            layout = master.prepare(say)
            self.segs = targets(self.sc, master.info.rated_current_mA, master.info.max_torque_pm)
            self.load = bus_load(Frames.of(layout), self.cycle_s, self.args.bitrate or 1_000_000)
            master.start_cycle()
            master.enable(say)
            self._play(master)
            code, reason = 0, "profile done"
        except Interrupted as exc:
            code, reason = (130 if exc.signum == signal.SIGINT else 143), f"interrupted by {exc}"
        except PlanError as exc:
            code, reason = 2, f"bad input after reading the drive: {exc}"
        except (DriveRefused, DriveStopped) as exc:
            code, reason = 1, str(exc)
        except Exception as exc:  # noqa: BLE001 - every failure ends the same safe way
            code, reason = 1, f"FAILED: {type(exc).__name__}: {exc}"
        finally:
            ignore_signals()
            disabled, sw = False, None
            if master is not None:
                say(f"bench run: {reason}; disabling the drive")
                disabled, sw = master.shutdown(say)
                master.close()
            recorder.stop()
            self.record_error = getattr(recorder, "error", None)
        if not disabled and code in (0, 130, 143):
            reason += f"; the drive was NOT seen SWITCH ON DISABLED at the end (statusword {sw})"
            code = 1
        return self._results(code, reason, master, layout, disabled, sw)

    def _recorder(self) -> Any:
        log = self.partial / "candump.log"
        if cia402_bus(self.args).kernel_can:  # candump records a kernel's CAN interface
            from bench.run.record.sources import CandumpSource

            return CandumpSource(self.args.bus, log, follow=False)
        return _SharedBusRecorder(log)

    def _play(self, master: Master) -> None:
        t0 = time.monotonic()
        silence = max(1.0, 20 * self.cycle_s)
        end = t0 + self.sc.periods * self.cycle_s
        say(f"  OPERATION ENABLED; playing {self.sc.periods} cycles ({self.sc.periods * self.cycle_s:.2f} s)")
        pending = list(self.segs)
        while True:
            now = time.monotonic()
            while pending and now >= t0 + pending[0].start_cycle * self.cycle_s:
                master.set_target(pending.pop(0).per_mille)
            master.check(silence)
            if now >= end:
                break
            time.sleep(min(self.cycle_s, 0.05))
        master.set_target(0)

    def _results(
        self, code: int, reason: str, master: Master | None, layout: Layout | None, disabled: bool, sw: int | None
    ) -> int:
        cand = self.partial / "candump.log"
        if cand.exists():
            cand.rename(self.partial / "bus.log")
        summary: dict[str, Any] = {
            "verdict": "ok" if code == 0 else "stopped",
            "exit_code": code,
            "reason": reason,
            "timing": NO_LOCKSTEP,
            "lockstep": False,
            "scenario": self.sc.name,
            "bus": self.args.bus,
            "record_error": self.record_error,
            "drive_id": self.args.drive_id,
            "cycle_ms": self.cycle_s * 1e3,
            "bus_load": self.load,
            "ignored_scenario_keys": ignored_keys(self.sc),
            "targets": [s.__dict__ for s in self.segs],
            "watches_bench": bool(master and master.info.watches_bench),
            "drive": master.info.__dict__ if master else None,
            "layout": layout.to_json() if layout else None,
            "final_statusword_sdo": sw,
            "final_state": "SWITCH ON DISABLED" if disabled else ("unknown" if sw is None else f"0x{sw:04X}"),
            "states_passed": [],
            "cycles": 0,
            "cycles_without_statusword": None,
            "tracking": [],
            "folder": str(self.out),
        }
        if layout is not None and (self.partial / "bus.log").exists():
            try:
                trace = decode_log(self.partial / "bus.log", layout, self.eds)
                summary.update(
                    states_passed=states_passed(trace),
                    cycles=len(trace),
                    cycles_without_statusword=trace.cycles_without_statusword,
                    tracking=tracking(trace),
                )
                write_csv(trace, self.partial / "trace.csv")
                write_plot(
                    trace, self.partial / "overview.png", f"{self.sc.name}: CST on drive 0x{self.args.drive_id:02X}"
                )
            except Exception as exc:  # noqa: BLE001 - the summary says what failed
                summary["decode_error"] = f"{type(exc).__name__}: {exc}"
        write_summary(self.partial / "summary.json", summary)
        if self.out.exists():
            self.out.rmdir()
        self.partial.rename(self.out)
        print(summary_text(summary), flush=True)
        return code


class _SharedBusRecorder:
    """Other python-can interfaces: every frame the master's own bus handle receives and sends, in candump's
    format. Through the master's handle, not a second one: an SLCAN adapter (a serial port, the CAN box's tap,
    a TCP socket) or a USB adapter's channel takes one client only, and a frame the master sends is not
    received back on most of them. (An interface whose periodic tasks run in its hardware, as IXXAT's do,
    sends SYNC and heartbeat past bus.send: those are then missing from the log.)"""

    def __init__(self, path: Path) -> None:
        import can

        self.logger = can.Logger(str(path))
        self.network: Any = None
        self._send: Any = None
        self._log: Any = None
        self.error: str | None = None  # the first failure to write the log

    def attach(self, network: Any) -> None:
        """Log what `network` (a connected canopen.Network) receives and what its bus sends from now on (SDO,
        NMT, the periodic SYNC and heartbeat tasks: python-can's threads call the bus's send), one line at a
        time (the notifier's thread and the senders' threads write to one file)."""
        import threading

        import can

        bus, logger, lock = network.bus, self.logger, threading.Lock()
        send = bus.send

        def log(msg: can.Message) -> None:
            with lock:
                try:
                    logger.on_message_received(msg)
                except (OSError, ValueError) as exc:  # a closed or full log: the summary says so, the bus goes on
                    self.error = self.error or f"{type(exc).__name__}: {exc}"

        def send_and_log(msg: can.Message, timeout: float | None = None) -> None:
            t = time.time()
            send(msg, timeout)
            sent = can.Message(
                timestamp=t,
                arbitration_id=msg.arbitration_id,
                is_extended_id=msg.is_extended_id,
                is_remote_frame=msg.is_remote_frame,
                dlc=msg.dlc,
                data=msg.data,
                channel=msg.channel,
                is_rx=False,
            )
            log(sent)

        bus.send = send_and_log
        self.network, self._send, self._log = network, send, log
        network.notifier.add_listener(log)

    def stop(self) -> None:
        if self.network is not None:
            self.network.notifier.remove_listener(self._log)
            if self.network.bus is not None:
                self.network.bus.send = self._send
        self.logger.stop()
