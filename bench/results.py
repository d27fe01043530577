"""From a capture to results: the CAN log (python-can writers), traces.npz, summary.json,
PNG plots and the Rerun recording."""

from __future__ import annotations

import json
from pathlib import Path

import can
import numpy as np

from .layout import BusLayout
from .metrics import step_metrics
from .plan import classic_frame_bits
from .eds import load as load_od
from .traces import check_continuity, decode, references_from_sdo, save

SUMMARY_VERSION = 1


def write_log(frames: np.ndarray, path: Path, channel: str) -> None:
    """Every frame, written by python-can's own writer for the extension (.log candump, .asc, .blf)."""
    with can.Logger(str(path)) as log:  # type: ignore[abstract]
        for f in frames:
            n = int(f["dlc"])
            log.on_message_received(can.Message(timestamp=float(f["t_us"]) * 1e-6, arbitration_id=int(f["cob_id"]),
                                                is_extended_id=False, dlc=n, data=bytes(f["data"][:n]),
                                                channel=channel))


def recorded_references(frames: np.ndarray, layout: BusLayout) -> list[tuple[int, str, float]]:
    """Reference steps as they were sent on the bus (SDO writes to the drive's References)."""
    od = load_od("drive")
    refs = od["References"]
    subs = {refs[name].subindex: name for name in ("iq_ref_A", "id_ref_A")}
    return references_from_sdo(frames, layout.drive_id, refs.index, subs, layout.sync_cob_id)


def summarize(out: Path, log_ext: str = ".log") -> dict[str, object]:
    cap = json.loads((out / "capture.json").read_text())
    layout = BusLayout.load(out / "layout.json")
    frames = np.load(out / "frames.npy")
    pp = int(cap["plant"].get("pole_pairs", 1))
    ts = float(cap["plant"].get("Ts_s", 1.0))
    refs = recorded_references(frames, layout)
    tr = decode(frames, layout, pp, ts, refs)
    save(out / "traces.npz", tr)
    log_path = out / f"bus{log_ext}"
    write_log(frames, log_path, cap["bus"])
    steps = [m.to_dict() for sig, ref in (("iq", "iq_ref_A"), ("id", "id_ref_A"))
             for m in step_metrics(tr[f"{sig}_A"], tr[ref], sig)]
    tuning = sorted((p, v) for p, k, v in cap.get("applied", []) if k == "controller.enable")
    for s in steps:
        on = [v for p, v in tuning if p <= s["at_period"]]
        s["tuning_on"] = bool(on and on[-1])
    cont = check_continuity(tr)
    bits = sum(classic_frame_bits(int(d)) for d in frames["dlc"])
    n = max(1, len(tr["period"]))
    ident = cap["identified"]
    summary = {
        "schema_version": SUMMARY_VERSION,
        "scenario": cap["scenario"],
        "bus": cap["bus"],
        "periods": int(n),
        "Ts_s": ts,
        "steps": steps,
        "identified": {"K1_avg_V_A": ident.get("K1_avg"), "K2_avg_V_A": ident.get("K2_avg"),
                       "L_hat_H": ident.get("L_hat_H"), "K1_active_V_A": ident.get("K1_active_V_A"),
                       "K2_active_V_A": ident.get("K2_active_V_A"), "identifications": ident.get("identifications"),
                       "gain_updates": ident.get("gain_updates")},
        "plant": cap["plant"],
        "controller": cap["controller"],
        "bus_stats": {"frames": int(len(frames)), "frames_per_period": len(frames) / n,
                      "lost_frames": cont["sync_counter_gaps"] + cont["missing_measurements"]
                      + cont["missing_commands"],
                      **cont,
                      "plant_missed_commands": cap["counters"]["plant_missed_commands"],
                      "plant_late_commands": cap["counters"]["plant_late_commands"],
                      "drive_lost_measurements": cap["counters"]["drive_lost_measurements"],
                      "drive_late_measurements": cap["counters"]["drive_late_measurements"],
                      "bits_per_period_worst_case": bits / n,
                      "bus_load_1Mbit_at_Ts": bits / n / 1e6 / ts},
        "timing": {"wall_s": cap["wall_s"], "run_wall_s": cap["run_wall_s"],
                   "periods_per_s": n / cap["run_wall_s"] if cap["run_wall_s"] > 0 else None},
        "files": {"log": log_path.name, "traces": "traces.npz", "layout": "layout.json"},
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def format_table(summary: dict[str, object]) -> str:
    lines = [f"{'step':<8}{'at':>7}{'from->to A':>14}{'settle':>8}{'overshoot':>16}{'ss err A':>11}{'tuning':>8}"]
    for s in summary["steps"]:  # type: ignore[union-attr]
        settle = "-" if s["periods_to_settle"] is None else str(s["periods_to_settle"])
        lines.append(f"{s['signal']:<8}{s['at_period']:>7}{s['from_A']:>7.2f}->{s['to_A']:<6.2f}{settle:>8}"
                     f"{s['overshoot_A']:>9.3f} A {s['overshoot_pct']:>4.1f}%{s['steady_state_error_A']:>11.2e}"
                     f"{('on' if s.get('tuning_on') else 'off'):>8}")
    return "\n".join(lines)
