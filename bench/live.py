"""Live view of a run whose bus lives elsewhere (the VM): follow the recorder's log file on
the shared file system and stream the decoded periods to a viewer as they arrive.

The recorder (candump, line-buffered) appends to `candump.log` in the run folder, which the
VM shares with the host; the capture writes `layout.json` and `plant.json` once the nodes
are configured. No network connection between the VM and the host is needed.
"""

from __future__ import annotations

import io
import json
import threading
from collections.abc import Callable
from pathlib import Path

import can
import numpy as np

from .layout import BusLayout
from .runner import frames_from_messages
from .traces import decode

OnTraces = Callable[[dict[str, np.ndarray], int, int], None]


class LiveTail(threading.Thread):
    def __init__(self, folder: Path, on_traces: OnTraces, interval_s: float = 0.5) -> None:
        super().__init__(daemon=True, name="bench-live-tail")
        self.folder = folder
        self.on_traces = on_traces
        self.interval_s = interval_s
        self.stop_event = threading.Event()
        self.messages: list[can.Message] = []
        self.sent = 0          # periods already streamed
        self._pos = 0
        self._rest = ""
        self.errors: list[str] = []

    def poll(self) -> int:
        """Read what was appended since the last call; stream complete periods. Returns periods streamed."""
        log = self.folder / "candump.log"
        layout_path, plant_path = self.folder / "layout.json", self.folder / "plant.json"
        if not (log.exists() and layout_path.exists() and plant_path.exists()):
            return 0
        with open(log, "r", errors="replace") as fh:
            fh.seek(self._pos)
            chunk = fh.read()
            self._pos = fh.tell()
        text = self._rest + chunk
        lines, _, self._rest = text.rpartition("\n")
        if lines:
            self.messages.extend(can.io.CanutilsLogReader(io.StringIO(lines + "\n")))
        if not self.messages:
            return 0
        layout = BusLayout.load(layout_path)
        plant = json.loads(plant_path.read_text())
        tr = decode(frames_from_messages(self.messages), layout, int(plant["pole_pairs"]), float(plant["Ts_s"]))
        complete = len(tr["period"]) - 1  # the last period may still be missing frames
        if complete > self.sent:
            self.on_traces(tr, self.sent, complete)
            n = complete - self.sent
            self.sent = complete
            return n
        return 0

    def run(self) -> None:
        while not self.stop_event.wait(self.interval_s):
            try:
                self.poll()
            except Exception as exc:  # noqa: BLE001 - a live view must never break the run
                self.errors.append(str(exc))
        try:
            self.poll()
        except Exception as exc:  # noqa: BLE001
            self.errors.append(str(exc))

    def stop(self) -> None:
        self.stop_event.set()
        self.join(timeout=10)
