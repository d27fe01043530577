"""The CAN box as a pytest session sees it (docs/CI.md, "The box in a CI log").

A session's vcan runs on a host without kernel CAN share one CAN box (bench/run/bus/box, docs/VM.md). The plugin
boots it itself before the first run that needs it (in the test's setup when the test's bus is the box's, else
in the hil_run call), so that the wait is said as it starts and when it ends, through pytest's terminal reporter
and not into the test's captured output:

    hil: booting the CAN box for test_motor.py::test_step (this host's kernel has no SocketCAN (...)); ...
    hil: the CAN box is up: booted in 97.3 s for test_motor.py::test_step

In an xdist worker the first line goes to the worker's standard error, the controller's own (execnet gives the
worker its parent's; nothing else leaves a worker while its test runs), and the second rides on the test's report
to the controller, which prints it (pytest_runtest_logreport). At the session's end one line (summary_line):

    hil: CAN box: booted once by this session (97.3 s, gw0); 6 runs in it, slots 1, 2; stopped at the session's end
    (this session booted it)

The session stops only a box its own runs booted: they inherit a token of the session (BENCH_BOX_OWNER), which the
box records (life.BoxInfo.booted_by); a box that was up before, or that a user or another session started, stays
up, as does one a run of another process holds a slot of.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time
import uuid
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from typing import Any

import pytest

LIVE_HINT = "~30-120 s, once: the session's later vcan runs share it"


@dataclass
class BoxLog:
    """What a session (or one xdist worker of it) did with the CAN box."""

    token: str | None = None  # BENCH_BOX_OWNER of the session's runs
    env_before: str | None = None  # BENCH_BOX_OWNER before the session set it
    up_before: str | None = None  # a box up at the session's start: who booted it
    boots: list[dict[str, Any]] = field(default_factory=list)  # {"test", "reason", "s", "worker"}
    runs: int = 0  # hil_run runs through the box
    slots: set[int] = field(default_factory=set)  # the slots they used
    pending: list[str] = field(default_factory=list)  # a worker's lines for the controller, on its next report
    cancelled: str | None = None  # how the session was cut short: "cancelled by SIGTERM", "interrupted"
    end: str | None = None  # what the session's end did with the box
    down: bool = False  # whether the box was down at the session's end
    ours_at_end: bool = False  # the box up at the session's end was booted by one of its runs (not by ensure)

    def export(self) -> dict[str, Any]:
        return {"boots": self.boots, "runs": self.runs, "slots": sorted(self.slots), "cancelled": self.cancelled}

    def merge(self, data: dict[str, Any]) -> None:
        """A worker's log (its workeroutput) into the controller's."""
        self.boots += list(data.get("boots") or [])
        self.runs += int(data.get("runs") or 0)
        self.slots |= set(data.get("slots") or [])
        self.cancelled = self.cancelled or data.get("cancelled")


BOX = pytest.StashKey[BoxLog]()


def _worker(config: pytest.Config) -> str | None:
    """The xdist worker's id (gw0, ...) in a worker, None in the controller or a session without xdist."""
    workerinput = getattr(config, "workerinput", None)
    return str(workerinput.get("workerid", "?")) if workerinput is not None else None


def log_of(config: pytest.Config) -> BoxLog:
    log = config.stash.get(BOX, None)
    if log is None:
        log = config.stash[BOX] = BoxLog(token=os.environ.get("BENCH_BOX_OWNER"))
    return log


def start(config: pytest.Config) -> None:
    """At the session's start (the controller's, or the only process's): the token its runs inherit (the xdist
    workers too, started after it), and the box up now if one is."""
    from bench.run.bus.box import life

    if _worker(config) is not None:
        log_of(config)
        return
    log = config.stash[BOX] = BoxLog(env_before=os.environ.get(life.OWNER_ENV))
    info = life.read_info()
    if info is not None:
        log.up_before = info.booted_by or "bench box up or a bench run outside a pytest session"
    log.token = os.environ[life.OWNER_ENV] = f"pytest-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    config.add_cleanup(lambda: finish(config))  # when the session ends before its pytest_sessionfinish


def needs(bus: str, extra_args: Sequence[str] = ()) -> str | None:
    """Why a `bench run --bus BUS EXTRA_ARGS` goes through the CAN box (bench.run.bus.buses.box_wanted), or None:
    --drive mcu and the emulated controllers boot a VM of their own."""
    args = list(extra_args)
    if _option(args, "--drive") == "mcu":
        return None
    from bench.run.bus.buses import choose_bus

    return choose_bus(bus, drive_bus=_option(args, "--drive-bus"), force_box="--box" in args).box_why()


def _option(args: list[str], name: str) -> str | None:
    """The value of `name` in `bench run` arguments (NAME VALUE or NAME=VALUE), the last one given."""
    found = None
    for i, a in enumerate(args):
        if a == name and i + 1 < len(args):
            found = args[i + 1]
        elif a.startswith(name + "="):
            found = a.split("=", 1)[1]
    return found


def say(config: pytest.Config, line: str, later: bool = False) -> None:
    """A line on the session's terminal now, through pytest's terminal reporter with the capture suspended. In an
    xdist worker: `later`, with the test's next report to the controller; else now, on the worker's standard
    error (the controller's)."""
    worker = _worker(config)
    if worker is not None and later:
        log_of(config).pending.append(f"[{worker}] {line}")
        return
    capman = config.pluginmanager.get_plugin("capturemanager")
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    with capman.global_and_fixture_disabled() if capman is not None else nullcontext():
        if worker is None and reporter is not None:
            reporter.write_line(line)
        else:
            sys.stderr.write(f"\n[{worker}] {line}\n" if worker else f"{line}\n")
            sys.stderr.flush()


def ensure(config: pytest.Config, test: str, reason: str) -> None:
    """The CAN box up for a run of `test`: booted now if none is, saying so as it starts and when it is up (its
    time), or the wait for one that another process is booting. BoxError when it does not come up."""
    from bench.run.bus.box import life

    if life.read_info() is not None and life.is_ready():
        return
    booted: list[bool] = []

    def starting(text: str) -> None:
        if booted:  # a later line of the boot (a KVM attempt that failed): as it is
            say(config, f"hil: {text.removeprefix('bench: ')}", later=True)
            return
        booted.append(True)
        say(config, f"hil: booting the CAN box for {test} ({reason}); {LIVE_HINT}")

    t0 = time.monotonic()
    life.up(say=starting)
    took = time.monotonic() - t0
    if booted:
        log_of(config).boots.append({"test": test, "reason": reason, "s": round(took, 1), "worker": _worker(config)})
        say(config, f"hil: the CAN box is up: booted in {took:.1f} s for {test}", later=True)
    elif took >= 1.0:
        say(config, f"hil: the CAN box is up: waited {took:.1f} s for another process's boot of it ({test})", True)


class SlotWatch:
    """Which slot of the box a `bench run` takes: its slot-N.json names its PID (life.status reads the same)."""

    def __init__(self) -> None:
        self.slot: int | None = None
        self._done = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self, pid: int) -> None:
        self._thread = threading.Thread(target=self._watch, args=(pid,), daemon=True)
        self._thread.start()

    def _watch(self, pid: int) -> None:
        from bench.run.bus.box import life

        while not self._done.is_set():
            for meta in life.BOX_DIR.glob("slot-*.json"):
                try:
                    if json.loads(meta.read_text()).get("pid") == pid:
                        self.slot = int(meta.stem.removeprefix("slot-"))
                        return
                except (OSError, ValueError):
                    continue
            self._done.wait(0.2)

    def stop(self) -> int | None:
        self._done.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        return self.slot


def record_run(config: pytest.Config, slot: int | None) -> None:
    log = log_of(config)
    log.runs += 1
    if slot is not None:
        log.slots.add(slot)


def finish(config: pytest.Config) -> None:
    """At the session's end (once): a worker hands its log to the controller (workeroutput); the controller, or
    the only process, stops the box if its runs booted it and no other process's run holds a slot of it (the
    signals held off meanwhile: a second Ctrl-C must not leave a QEMU behind), and says why it did or did not."""
    log = config.stash.get(BOX, None)
    if log is None or log.end is not None:
        return
    workeroutput = getattr(config, "workeroutput", None)
    if workeroutput is not None:
        log.end = "worker"
        workeroutput["hil_box"] = log.export()
        return
    from bench.run.bus.box import life
    from bench.stop import deferred

    if log.env_before is None:
        os.environ.pop(life.OWNER_ENV, None)
    else:
        os.environ[life.OWNER_ENV] = log.env_before
    info = life.read_info()
    idle = f"{info.idle_timeout_s:g} s" if info is not None else ""
    log.ours_at_end = info is not None and info.booted_by == log.token
    if info is None:
        log.down = True
        log.end = "down at the session's end" + _last_end()
    elif info.booted_by != log.token:
        who = log.up_before or info.booted_by or "a user or a bench run outside this session"
        log.end = f"left up: this session did not boot it ({who}); bench box down or {idle} unused stops it"
    elif life.slots_held_by_others(info, owner=log.token):
        log.end = f"left up: another process's run holds a slot of it; it powers off after {idle} unused"
    else:
        with deferred():
            life.down()
        log.down = True
        cancelled = f"; the session was {log.cancelled}" if log.cancelled else ""
        log.end = f"stopped at the session's end (this session booted it{cancelled})"


def _last_end() -> str:
    from bench.run.bus.box import life

    try:
        why = json.loads((life.BOX_DIR / "exit.json").read_text()).get("why")
    except (OSError, ValueError, AttributeError):
        return ""
    return f" (it ended: {why})" if why else ""


def summary_line(log: BoxLog) -> str | None:
    """The session's one line on the box, or None when it used none."""
    if not log.boots and not log.runs:
        return None
    if log.boots:
        n = len(log.boots)
        each = ", ".join(f"{b['s']:.1f} s" + (f", {b['worker']}" if b.get("worker") else "") for b in log.boots)
        head = f"booted {'once' if n == 1 else f'{n} times'} by this session ({each})"
    elif log.ours_at_end and log.up_before:  # the box of before ended, and a run of this session booted another
        head = "booted by a run of this session (the one up before it ended)"
    elif log.up_before and not log.ours_at_end:
        head = "up before this session"
    else:
        head = "booted by a run of this session"
    runs = f"{log.runs} run{'s' if log.runs != 1 else ''} in it"
    if log.slots:
        runs += f", slot{'s' if len(log.slots) > 1 else ''} {', '.join(map(str, sorted(log.slots)))}"
    return f"hil: CAN box: {head}; {runs}; {log.end or 'state unknown'}"


class BoxHooks:
    """The session's hooks for the box (a plugin of its own: the hooks that are not given the config)."""

    def __init__(self, config: pytest.Config, cancel: Any) -> None:
        self.config = config
        self.cancel = cancel  # cancel.Cancel: the signal that cancelled the session, if one did
        self._merged: set[str] = set()  # the workers whose log is merged

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """The controller prints a worker's box lines (say(..., later=True)) as their report comes in."""
        lines = getattr(report, "hil_box_lines", None)
        if lines and _worker(self.config) is None:
            reporter = self.config.pluginmanager.get_plugin("terminalreporter")
            for line in lines:
                reporter.write_line(line) if reporter is not None else print(line)

    @pytest.hookimpl(trylast=True)  # after the skip marks and the hil marker's checks: a skipped test boots nothing
    def pytest_runtest_setup(self, item: pytest.Item) -> None:
        """A hil_run test whose bus is the CAN box's: the box booted in its setup if none is up (ensure says so as
        it starts and when it is up; in a worker the second line rides on the setup's report)."""
        if "hil_run" not in getattr(item, "fixturenames", ()):
            return
        from bench.pytest_plugin.state import SETTINGS

        marker = item.get_closest_marker("hil")
        given = marker.kwargs if marker is not None else {}
        reason = needs(given.get("bus") or self.config.stash[SETTINGS].bus)
        if reason is None or given.get("drive") == "mcu":  # the image's VM is its own
            return
        from bench.run.bus.box.control import BoxError

        try:
            ensure(self.config, item.nodeid, reason)
        except BoxError as exc:
            pytest.fail(f"hil: {exc}", pytrace=False)

    @pytest.hookimpl(optionalhook=True)
    def pytest_testnodedown(self, node: Any, error: object) -> None:
        """An xdist worker's box log (its workeroutput) into the session's."""
        data = (getattr(node, "workeroutput", None) or {}).get("hil_box")
        key = str(getattr(getattr(node, "gateway", None), "id", id(node)))
        if data and key not in self._merged:  # xdist calls it twice for a worker's Ctrl-C
            self._merged.add(key)
            log_of(self.config).merge(data)

    @pytest.hookimpl(trylast=True)  # after xdist's own: its workers have ended
    def pytest_sessionfinish(self, exitstatus: int) -> None:
        log = log_of(self.config)
        if self.cancel.signal:
            log.cancelled = f"cancelled by {self.cancel.signal}"
        elif exitstatus == pytest.ExitCode.INTERRUPTED and not log.cancelled:
            log.cancelled = "interrupted"  # Ctrl-C of a session without xdist: pytest's own
        finish(self.config)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        log = self.config.stash.get(BOX, None)
        line = summary_line(log) if log is not None and _worker(self.config) is None else None
        if line:
            terminalreporter.write_line(line)
