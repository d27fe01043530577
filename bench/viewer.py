"""Rerun view of a run: traces logged with Rerun's columnar API (send_columns, one call
per signal and batch, never one call per sample), on the timelines `period` (the
control-period index) and `sim_time` (simulated seconds), under a blueprint that lays
out currents with references, voltages, mechanics, identification and bus statistics.

Every run saves `run.rrd`; `--serve` also serves it to the web viewer; the viewer is
spawned when a display exists and `--no-viewer` is not given.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

GROUPS: dict[str, tuple[str, ...]] = {
    "currents": ("iq_A", "iq_ref_A", "id_A", "id_ref_A"),
    "voltages": ("vq_V", "vd_V", "v_alpha_V", "v_beta_V"),
    "mechanics": ("theta_m_rad",),
    "identification": ("det_A2", "K1_hat", "K1_active_V_A", "L_hat_H"),
    "bus": ("sync_counter", "status"),
}


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/currents", name="currents and references (A)"),
            rrb.TimeSeriesView(origin="/voltages", name="voltage commands (V)"),
            rrb.Horizontal(
                rrb.TimeSeriesView(origin="/identification", name="det, identified gains, L_hat"),
                rrb.TimeSeriesView(origin="/mechanics", name="position / speed"),
                rrb.TimeSeriesView(origin="/bus", name="bus: SYNC counter, status"),
            ),
        ),
        collapse_panels=True,
    )


class Viewer:
    """A Rerun recording of one run: always saved to `rrd` (full rate), and teed to a
    spawned viewer or a served web viewer (possibly decimated) when asked."""

    def __init__(self, name: str, rrd: Path, serve: bool = False, spawn: bool | None = None,
                 live_memory_limit: str = "1GiB") -> None:
        self.rrd = rrd
        self.file = rr.RecordingStream("pmsm-hil-bench", recording_id=name)
        self.file.set_sinks(rr.FileSink(str(rrd)), default_blueprint=blueprint())
        self.live: rr.RecordingStream | None = None
        if spawn is None:
            spawn = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
        if serve or spawn:
            self.live = rr.RecordingStream("pmsm-hil-bench", recording_id=name)
            try:
                if serve:
                    uri = self.live.serve_grpc(server_memory_limit=live_memory_limit)
                    rr.serve_web_viewer(connect_to=uri)
                    print(f"rerun: web viewer serving {uri}")
                else:
                    self.live.spawn(memory_limit=live_memory_limit)
                self.live.send_blueprint(blueprint())
            except Exception as exc:  # noqa: BLE001 - the saved .rrd still works
                print(f"rerun: no live viewer ({exc}); the recording is saved to {rrd}")
                self.live = None

    @staticmethod
    def _send(rec: rr.RecordingStream, tr: dict[str, np.ndarray], sl: slice) -> None:
        period = tr["period"][sl]
        if len(period) == 0:
            return
        times = [rr.TimeColumn("period", sequence=period), rr.TimeColumn("sim_time", duration=tr["t_s"][sl])]
        for group, names in GROUPS.items():
            for name in names:
                if name in tr:
                    rec.send_columns(f"/{group}/{name}", indexes=times,
                                     columns=rr.Scalars.columns(scalars=np.asarray(tr[name][sl], float)))

    def log(self, tr: dict[str, np.ndarray], start: int = 0, stop: int | None = None, live_decimate: int = 1) -> None:
        """Send periods [start, stop): full rate to the file, decimated to the live viewer."""
        stop = len(tr["period"]) if stop is None else stop
        self._send(self.file, tr, slice(start, stop))
        if self.live is not None:
            self._send(self.live, tr, slice(start, stop, max(1, live_decimate)))

    def close(self) -> None:
        self.file.flush()
        if self.live is not None:
            self.live.flush()
