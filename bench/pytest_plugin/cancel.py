"""A cancelled session (docs/CI.md, "Cancelling a job"): SIGTERM, and under xdist SIGINT too.

Without this, SIGTERM ends pytest at once, its cleanup unrun: the CAN box the session booted stays up for its idle
time (600 s, a 2 GB VM), and under xdist the workers, their controller gone, print `OSError: cannot send (already
closed?)` tracebacks. Here a signal cancels the test that runs and the session stops after it, through pytest's
own `shouldstop`, so that the session's end runs (box.finish stops the box it booted):

- one process (no xdist): SIGTERM cancels the running test: whatever it waits for is interrupted (its `bench
  run` is stopped by hil_run and gives its box slot back), the test is reported skipped, "cancelled by SIGTERM",
  and pytest stops after it ("Interrupted: cancelled by SIGTERM", exit status 2). Ctrl-C is pytest's own. A
  second SIGTERM interrupts at once.
- an xdist worker: the first SIGTERM or SIGINT does the same in the worker, which then ends; its `shouldstop`
  makes the controller end the session (no crash reported, no worker started in its place). Between tests it
  takes the signal as the controller's `shutdown` command. Later signals are ignored, so that its cleanup runs
  to its end.
- the xdist controller: the first SIGTERM or SIGINT is passed on to its workers as SIGTERM (a terminal's Ctrl-C
  reaches them too: a second signal changes nothing there), and the session ends when they have. A second
  signal, or PASS_ON_S without an end, interrupts the controller at once.
"""

from __future__ import annotations

import _thread
import os
import signal
import threading
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

PASS_ON_S = 90.0  # the controller's wait for its workers' end (a bench run's stop takes seconds; hil_run waits 60)


class Cancel:
    """The session's stop signals, a plugin of its own (register): installed at the session's start (main thread,
    only over the default handlers), restored at its end; the running test's phase kept for them."""

    def __init__(self, config: pytest.Config) -> None:
        self.worker = hasattr(config, "workerinput")
        self.controller = False  # an xdist controller (its DSession is known once every plugin is configured)
        self.session: pytest.Session | None = None
        self.phase: str | None = None  # setup, call, teardown of the running test
        self.signal: str | None = None  # the first signal received ("SIGTERM")
        self._old: dict[int, Any] = {}
        self._timer: threading.Timer | None = None

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionstart(self, session: pytest.Session) -> None:
        self.session = session
        self.controller = not self.worker and session.config.pluginmanager.has_plugin("dsession")
        self.install()

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_setup(self, item: pytest.Item) -> Generator[None, None, None]:
        return (yield from self._phase("setup"))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_call(self, item: pytest.Item) -> Generator[None, None, None]:
        return (yield from self._phase("call"))

    @pytest.hookimpl(wrapper=True)
    def pytest_runtest_teardown(self, item: pytest.Item) -> Generator[None, None, None]:
        return (yield from self._phase("teardown"))

    def _phase(self, name: str) -> Generator[None, None, None]:
        self.phase = name
        try:
            return (yield)
        finally:
            self.phase = None

    def pytest_unconfigure(self) -> None:
        self.restore()

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        wanted = {signal.SIGTERM: signal.SIG_DFL}
        if self.worker or self.controller:
            wanted[signal.SIGINT] = signal.default_int_handler
        for signum, default in wanted.items():
            if signal.getsignal(signum) is default:  # never over a handler someone else set
                self._old[signum] = signal.signal(signum, self._on_signal)

    def restore(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        for signum, old in self._old.items():
            if signal.getsignal(signum) == self._on_signal:
                signal.signal(signum, old)
        self._old.clear()

    def _on_signal(self, signum: int, frame: Any) -> None:
        __tracebackhide__ = True  # pytest's interrupted line names the frame the signal interrupted, not this one
        name = signal.Signals(signum).name
        first = self.signal is None
        self.signal = self.signal or name
        if self.controller:
            if first and self._pass_on(name):
                return
            raise KeyboardInterrupt(f"{name}: the session is cancelled")
        if not first:
            if self.worker:
                return  # its cleanup runs to its end
            raise KeyboardInterrupt(f"{name}: the session is cancelled")
        if self.session is not None:
            self.session.shouldstop = f"cancelled by {name}"
        if self.phase in ("setup", "call"):
            # reported skipped, at the test's own location (not the frame the signal interrupted)
            raise pytest.skip.Exception(
                f"cancelled by {name}: the test was stopped, and the session stops after it", _use_item_location=True
            )
        if self.phase == "teardown" or (self.worker and self._shutdown()):
            return  # a test's teardown is short: the session stops after it
        raise KeyboardInterrupt(f"{name}: the session is cancelled")

    def _shutdown(self) -> bool:
        """An xdist worker between tests (waiting for its next one): the controller's own `shutdown` command given
        to it (its WorkerInteractor), so that it ends as asked, with its `shouldstop`; False without one."""
        if self.session is None:
            return False
        for plugin in self.session.config.pluginmanager.get_plugins():
            if hasattr(plugin, "handle_command") and hasattr(plugin, "torun"):
                plugin.handle_command(("shutdown", {}))
                return True
        return False

    def _pass_on(self, name: str) -> bool:
        """The controller's first signal: SIGTERM to each worker (they end their tests, then the session ends), a
        timer that interrupts the controller if they have not within PASS_ON_S. False when it has no worker."""
        workers = _children()
        for pid in workers:
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
        if not workers:
            return False
        os.write(
            2,
            f"\nhil: {name}: cancelling the session: its {len(workers)} workers stop their tests and runs first (a "
            "second signal ends it at once)\n".encode(),
        )
        signum = signal.Signals[name]
        self._timer = threading.Timer(PASS_ON_S, _thread.interrupt_main, args=(signum,))
        self._timer.daemon = True
        self._timer.start()
        return True


def _children() -> list[int]:
    """This process's child processes (/proc): an xdist controller's are its workers."""
    me, found = os.getpid(), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[-1].split()
        if len(fields) > 1 and fields[1] == str(me):
            found.append(int(entry.name))
    return found


CANCEL = pytest.StashKey[Cancel]()
