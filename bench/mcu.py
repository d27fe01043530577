"""The drive firmware as a Cortex-M4F image under QEMU (mps2-an386), reachable as a serial CAN adapter.

`make mcu` builds build/mcu/drive_mcu.elf: the portable drive firmware over the port layer
(firmware_shim/port) on the MPS2 AN386 board (firmware_shim/mcu/mps2_an386; docs/PORTING.md).
:class:`McuImage` builds it if needed, runs it in ``qemu-system-arm -M mps2-an386`` with UART0 (SLCAN)
on a free local TCP port and UART1 (the text console) in a file, and stops QEMU cleanly::

    with McuImage() as mcu:
        bus = mcu.open_bus()                # python-can slcan on socket://127.0.0.1:PORT
        ...                                 # CANopen node OD_DRIVE_DEFAULT_NODE_ID (drive.eds)

Virtual time: ``-icount shift=0`` makes every guest instruction take 1 ns of virtual time, so the
image's SysTick (25 MHz core clock) counts one tick per 40 instructions (:data:`INSTRUCTIONS_PER_TICK`);
the step cost the image publishes in 0x2208 (in ticks) times 40 is instructions per step.  While the
guest sleeps in WFI, QEMU lets the virtual clock follow the host's (icount sleep=on, the default).
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from types import TracebackType

import can

from bench.paths import BUILD, REPO
from bench.root import INSTALLED

ELF = BUILD / "mcu" / "drive_mcu.elf"
QEMU = "qemu-system-arm"
MACHINE = "mps2-an386"
SYSCLK_HZ = 25_000_000  # the image's SysTick clock (0x2208:04 cycle_clock_Hz)
INSTRUCTIONS_PER_TICK = 1_000_000_000 // SYSCLK_HZ  # -icount shift=0: 1 instruction = 1 ns
BOOT_LINE = "drive_mcu: node"


def build(quiet: bool = True) -> Path:
    """`make mcu` (make rebuilds only what changed); the ELF's path.  Raises if the toolchain is missing.
    An installed package's image (or a law's) was built with it: there is nothing to make, only to find."""
    if INSTALLED or os.environ.get("BENCH_BUILD_DIR"):
        if ELF.exists():
            return ELF
        raise FileNotFoundError(
            f"{ELF} is missing: the Cortex-M4F image is built with the package (or the law) when "
            "arm-none-eabi-gcc is installed: apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi, "
            "then reinstall (or rebuild the law)"
        )
    if shutil.which("arm-none-eabi-gcc") is None:
        raise FileNotFoundError("arm-none-eabi-gcc not found: apt-get install gcc-arm-none-eabi (or `make setup`)")
    res = subprocess.run(["make", "-C", str(REPO), "mcu"], capture_output=True, text=True, timeout=600)
    if res.returncode != 0:
        raise RuntimeError(f"make mcu failed:\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}")
    if not quiet:
        print(res.stdout[-600:])
    return ELF


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def qemu_command(elf: Path, port: int, console: Path | None) -> list[str]:
    """The QEMU 7.2 command line: UART0 = TCP server on `port` (no wait for a client), UART1 = `console`."""
    return [
        QEMU,
        "-M",
        MACHINE,
        "-nographic",
        "-monitor",
        "none",
        "-kernel",
        str(elf),
        "-serial",
        f"tcp:127.0.0.1:{port},server=on,wait=off,nodelay=on",
        "-serial",
        f"file:{console}" if console is not None else "null",
        "-icount",
        "shift=0",
    ]


class McuImage:
    """One QEMU running the drive image; :meth:`start` returns the SLCAN TCP port, :meth:`stop` ends QEMU."""

    def __init__(self, elf: Path | None = None, boot_timeout_s: float = 20.0) -> None:
        self.elf = elf
        self.boot_timeout_s = boot_timeout_s
        self.port = 0
        self.proc: subprocess.Popen[bytes] | None = None
        self._dir: tempfile.TemporaryDirectory[str] | None = None
        self.console_path: Path | None = None

    def start(self) -> int:
        if shutil.which(QEMU) is None:
            raise FileNotFoundError(f"{QEMU} not found: apt-get install qemu-system-arm (or `make setup`)")
        elf = self.elf if self.elf is not None else build()
        self._dir = tempfile.TemporaryDirectory(prefix="drive_mcu_")
        self.console_path = Path(self._dir.name) / "console.txt"
        self.console_path.touch()
        err = Path(self._dir.name) / "qemu.err"
        for _attempt in range(5):  # the port may be taken between free_port() and QEMU's bind
            self.port = free_port()
            with err.open("wb") as ferr:
                self.proc = subprocess.Popen(
                    qemu_command(elf, self.port, self.console_path),
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,
                    stderr=ferr,
                )
            if self._wait_boot():
                return self.port
            if self.proc.poll() is None:
                break  # running but silent: not a port clash
            self.proc = None
        text = err.read_text(errors="replace") if err.exists() else ""
        self.stop()
        raise RuntimeError(f"{QEMU} did not boot the image within {self.boot_timeout_s} s: {text[-2000:]}")

    def _wait_boot(self) -> bool:
        assert self.proc is not None and self.console_path is not None
        deadline = time.monotonic() + self.boot_timeout_s
        while time.monotonic() < deadline:
            if BOOT_LINE in self.console():
                return True
            if self.proc.poll() is not None:
                return False
            time.sleep(0.02)
        return False

    def console(self) -> str:
        """What the image wrote on UART1 so far."""
        if self.console_path is None or not self.console_path.exists():
            return ""
        return self.console_path.read_text(errors="replace")

    def open_bus(self, **kwargs: object) -> can.BusABC:
        """python-can's slcan interface on the image's UART0 (opened with `O`, closed with `C` at shutdown)."""
        if self.proc is None:
            raise RuntimeError("McuImage not started")
        return can.Bus(  # type: ignore[no-any-return]
            interface="slcan", channel=f"socket://127.0.0.1:{self.port}", sleep_after_open=0, **kwargs
        )

    def stop(self) -> None:
        """End QEMU (SIGTERM, then SIGKILL after 5 s) and remove the console file."""
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5)
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None
            self.console_path = None

    def __enter__(self) -> McuImage:
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()
