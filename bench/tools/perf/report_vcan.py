"""`bench perf`'s report, its vcan0 section: the real loop over vcan0 against lockstep_floor (the same
frames between two C processes), the target real/floor, and what the candump recorder saw of every frame
(bench/tools/perf/vcan.py measures it)."""

from __future__ import annotations

from typing import Any

from bench.tools.perf.common import TARGET_VCAN_RATIO

FLOORS = (
    ("floor_4", "floor, 4 frames (SYNC, 2 meas, cmd)"),
    ("floor_6", "floor, 6 frames (+2 drive trace PDOs)"),
    ("floor_6_recorded", "floor, 6 frames + candump recorder"),
)


def format_vcan(r: dict[str, Any], L: Any) -> None:
    """The lockstep-over-vcan0 section of the report (L: report._Lines); nothing when it was not run (--only),
    'skipped' when it was left out (--quick)."""
    if "vcan" not in r:
        return
    v = r.get("vcan")
    L.head("lockstep over vcan0")
    if v is None:
        L.append("  skipped (--quick)")
    elif not L.err(v):
        L.append(
            f"  where: {v['where']} (kernel {v.get('kernel')}, {v.get('logical_cpus')} CPUs), "
            f"{v['wall_s_including_boot']:.0f} s including boot"
        )
        _real_loop(v, L)
        _floors(v, L)
        _same_frames_target(v, L)
        ch = v.get("long_choice", {})
        L.append(
            f"  long run: {ch.get('periods')} periods chosen (measured rate x {ch.get('budget_s')} s budget, "
            f"target {ch.get('target_periods')})"
        )
        _recorders(v, L)


def _real_loop(v: dict[str, Any], L: Any) -> None:
    """The real loop's rate over vcan0, with the recorder and without it (that one against the 6-frame floor)."""
    lock = v.get("lockstep", {})
    if "error" in lock:
        L.append(f"  real loop ERROR: {lock['error']}")
    else:
        L.append(
            f"  real loop (capture_to_log, {lock['periods']} periods): {lock['periods_per_s']:.0f} periods/s "
            f"(run_wall_s {lock['run_wall_s']:.2f}; missed commands "
            f"{(lock.get('recorder') or {}).get('plant_missed_commands')})"
        )
    unrec = v.get("lockstep_unrecorded", {})
    if unrec and "error" not in unrec:
        fl6 = v.get("floor_6", {}).get("periods_per_s")
        ratio_u = unrec["periods_per_s"] / fl6 if fl6 else None
        L.append(
            f"  real loop without the recorder:            {unrec['periods_per_s']:8.0f} periods/s"
            + (f"; / floor of the same 6 frames {ratio_u:.2f}" if ratio_u else "")
        )


def _floors(v: dict[str, Any], L: Any) -> None:
    """lockstep_floor's rate and round-trip times per frame set, and the real loop over each floor."""
    for key, label in FLOORS:
        fl = v.get(key, {})
        if "error" in fl:
            L.append(f"  {label}: ERROR {fl['error']}")
            continue
        ratio = fl.get("real_over_floor")
        extra = ""
        if "frames_recorded" in fl:
            extra = f", recorded {fl['frames_recorded']}/{fl['frames_expected']} frames"
        L.append(
            f"  {label:<40} {fl['periods_per_s']:8.0f} periods/s  RTT median {fl['rtt_us']['median']:.0f} us "
            f"p99 {fl['rtt_us']['p99']:.0f} us" + (f"; real/floor {ratio:.2f}" if ratio else "") + extra
        )


def _same_frames_target(v: dict[str, Any], L: Any) -> None:
    """The target real/floor judged on the same frames on the same bus: the loop without its recorder against
    the 6-frame floor, and the recorded loop against the 6-frame floor with the same recorder."""
    fl6 = (v.get("floor_6", {}) or {}).get("periods_per_s")
    unrec_rate = (v.get("lockstep_unrecorded", {}) or {}).get("periods_per_s")
    rec_ratio = (v.get("floor_6_recorded", {}) or {}).get("real_over_floor")
    same = [r for r in ((unrec_rate / fl6) if unrec_rate and fl6 else None, rec_ratio) if r is not None]
    verdict = "meets" if same and min(same) >= TARGET_VCAN_RATIO else "MISSED"
    L.append(
        f"  target real/floor of the same frames >= {TARGET_VCAN_RATIO}: "
        + (", ".join(f"{x:.2f}" for x in same) + " -> " + verdict if same else "not measured")
    )


def _recorders(v: dict[str, Any], L: Any) -> None:
    """What the candump recorder of the real loop and of the long run saw: SYNCs and loop frames recorded, lost
    frames, continuity by kernel time stamp, and what candump's log order would have made of it."""
    for key in ("lockstep", "long"):
        part = v.get(key, {})
        rec = part.get("recorder")
        if "error" in part:
            L.append(f"  {key}: ERROR {part['error']}")
        elif rec is None:
            continue
        elif "error" in rec:
            L.append(f"  {key} recorder: ERROR {rec['error']}")
        else:
            c = rec["continuity"]
            L.append(
                f"  {key:<9} recorder: SYNCs {rec['syncs_recorded']}/{rec['periods_expected']}, loop frames "
                f"{rec['loop_frames_recorded']}/{rec['loop_frames_expected']}, lost {rec['lost_frames']} "
                f"(sync gaps {c['sync_counter_gaps']}, missing meas {c['missing_measurements']}, "
                f"missing cmds {c['missing_commands']}, index mismatches {c['sample_index_mismatches']}); "
                f"{part['periods_per_s']:.0f} periods/s"
            )
            cl = rec["continuity_in_log_order"]
            L.append(
                f"            decoded by kernel time stamp; in candump's log order "
                f"{rec['frames_out_of_time_order_in_log']} frames are out of time order -> "
                f"{cl['missing_commands']} commands would look missing, "
                f"{cl['missing_measurements']} measurements"
            )
