"""How a `bench` command stops: Ctrl-C (SIGINT) and SIGTERM both unwind the command through its
cleanup (the `except KeyboardInterrupt` paths stop the nodes, the VM, the viewer processes, the Dask
cluster), and the exit status says which: 130 (SIGINT) or 143 (SIGTERM), the shell's 128 + signal.

SIGTERM raises `Terminated`, a KeyboardInterrupt, so every cleanup written for Ctrl-C also runs for
`kill PID`, `timeout`, systemd or a CI runner stopping the command. `deferred()` holds both signals
off while a cleanup must run to its end (a second Ctrl-C must not leave a QEMU or a viewer behind).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

EXIT_SIGINT = 130
EXIT_SIGTERM = 143
EXIT_SIGPIPE = 141


class Terminated(KeyboardInterrupt):
    """SIGTERM, as a KeyboardInterrupt: the same cleanup runs."""


_received: list[int] = []  # the stop signals this process received, in order


def _on_term(signum: int, frame: Any) -> None:
    _received.append(signum)
    raise Terminated


def _on_int(signum: int, frame: Any) -> None:
    _received.append(signum)
    raise KeyboardInterrupt


def install() -> None:
    """SIGTERM raises Terminated; SIGINT raises KeyboardInterrupt (as Python's own handler, but
    recorded). Main thread only (a no-op elsewhere)."""
    if threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGTERM, _on_term)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_int)


def terminated() -> bool:
    """Whether a SIGTERM arrived."""
    return signal.SIGTERM in _received


def exit_status(default: int = EXIT_SIGINT) -> int:
    """130 after Ctrl-C, 143 after SIGTERM."""
    return EXIT_SIGTERM if terminated() else default


@contextmanager
def deferred() -> Iterator[list[int]]:
    """Within the block SIGINT and SIGTERM are recorded (in the yielded list), not raised: a cleanup
    runs to its end. Main thread only (elsewhere the signals are not delivered to Python anyway)."""
    got: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield got
        return

    def hold(signum: int, frame: Any) -> None:
        got.append(signum)
        _received.append(signum)

    old = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield got
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def spawn_ignoring_sigint(start: Callable[[], Any]) -> Any:
    """`start()` (a subprocess.Popen) with SIGINT ignored, which the child inherits through exec: a
    helper process that the bench stops itself is not hit by the terminal's Ctrl-C (Python keeps an
    inherited SIG_IGN for SIGINT), even while it is still importing. SIGINT is blocked meanwhile, so a
    Ctrl-C in that window is held (a blocked signal is never discarded), not lost: it arrives once the
    bench's own handler is back. The child inherits the blocked mask too: it unblocks SIGINT itself."""
    if threading.current_thread() is not threading.main_thread():
        return start()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        return start()
    finally:
        signal.signal(signal.SIGINT, old)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
