"""`bench perf`'s report for a person: one block per section, the pipeline section as a table of
targets (measured, target, ratio, met)."""

from __future__ import annotations

from typing import Any

from bench.tools.perf.common import TARGET_LOOP_MPS, TARGET_PLANT_MPS, TARGET_VCAN_RATIO


def _fmt_target(ok: bool | None) -> str:
    return "" if ok is None else ("meets" if ok else "MISSED")


class _Lines(list):  # type: ignore[type-arg]
    def head(self, title: str) -> None:
        self.append("")
        self.append(f"== {title} " + "=" * max(0, 70 - len(title)))

    def err(self, sec: dict[str, Any]) -> bool:
        if "error" in sec:
            self.append(f"  ERROR: {sec['error']}")
            return True
        return False

    def sec(self, r: dict[str, Any], key: str, title: str) -> dict[str, Any] | None:
        """The section under its title; None when it was not run (nothing printed: --only) or failed."""
        s = r.get(key)
        if s is None:
            return None
        self.head(title)
        return None if self.err(s) else s


def _cores(r: dict[str, Any], L: _Lines) -> None:
    m = L.sec(r, "machine", "machine")
    if m:
        for k in (
            "cpu_model",
            "logical_cpus",
            "cores",
            "kernel",
            "gcc",
            "arm_none_eabi_gcc",
            "clang",
            "valgrind",
            "python",
        ):
            L.append(f"  {k:<20} {m.get(k)}")
        L.append(f"  {'command':<20} {r.get('command')}")

    p = L.sec(r, "plant_core", f"plant core (plant_perf; target >= {TARGET_PLANT_MPS:.0f} M periods/s)")
    if p:
        L.append(f"  {p['periods_per_case']} periods per option set")
        L.append(f"  {'option set':<42}{'step ns':>9}{'M/s':>8}{'sample+step ns':>16}{'M/s':>8}  target")
        for c in p["cases"]:
            L.append(
                f"  {c['case']:<42}{c['step_ns']:>9.1f}{c['step_Mps']:>8.2f}{c['sample_step_ns']:>16.1f}"
                f"{c['sample_step_Mps']:>8.2f}  {_fmt_target(c['meets_target'])}"
            )
        if "rss_pages" in p:
            L.append(f"  plant_perf resident pages: {p['rss_pages']}")

    cl = L.sec(r, "closed_loop", f"plant + controller in-process (target >= {TARGET_LOOP_MPS:.0f} M periods/s)")
    if cl:
        b, d = cl["bare_cores"], cl["direct_mode"]
        L.append(
            f"  bare cores (hil_core_loop_ns)        {b['ns_per_period']:8.1f} ns/period  "
            f"{b['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(b['meets_target'])}"
            f"  (iq at end {b['iq_end_A']:.4f} A for 1 A)"
        )
        L.append(
            f"  direct mode (libhil.so + CANopen)    {d['ns_per_period']:8.1f} ns/period  "
            f"{d['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(d['meets_target'])}"
            f"  ({d['periods']} periods, missed commands {d['plant_missed_commands']})"
        )
        mem = cl["memory"]
        L.head("resident memory, direct mode (/proc/self/statm)")
        L.append(
            f"  RSS pages before {mem['rss_pages']['before']}, after 10^6 periods {mem['rss_pages']['after_1e6']}, "
            f"after 2x10^6 {mem['rss_pages']['after_2e6']}"
        )
        L.append(
            f"  growth {mem['rss_growth_kB_over_1e6']:.0f} kB over the first 10^6, "
            f"{mem['rss_growth_kB_second_1e6']:.0f} kB over the second -> {'flat' if mem['flat'] else 'NOT flat'}"
        )

    fw = L.sec(r, "firmware", "firmware core (drive_perf, host)")
    if fw:
        t = fw["timing_ns"]
        for k, label in (
            ("deadbeat_step_ns", "deadbeat current step"),
            ("deadbeat_ident_step_ns", "deadbeat + identification step"),
            ("pi_step_ns", "PI current step"),
            ("ident_sample_ns", "identification sample (per call)"),
            ("ident_update_ns", "identification update (You 2019 Eq. 28-32)"),
        ):
            if k in t:
                L.append(f"  {label:<40} {t[k]:8.1f} ns")
        cg = fw.get("callgrind", {})
        if "error" in cg:
            L.append(f"  callgrind: {cg['error']}")
        else:
            ips = cg["instructions_per_step"]
            L.append(f"  callgrind instructions (Ir, steps {cg['step_counts'][0]} vs {cg['step_counts'][1]}):")
            for k, label in (
                ("deadbeat", "deadbeat current step"),
                ("deadbeat_ident", "deadbeat + identification"),
                ("pi", "PI current step"),
                ("ident_sample", "identification sample"),
                ("ident_update", "identification update"),
            ):
                L.append(f"    {label:<38} {ips[k]:8.1f} instructions")

    sw = L.sec(r, "sweep_scaling", "bench sweep on Dask: 1,000 points of 2,000 periods; a 10^4-point study")
    if sw:
        for w, run in sw["runs"].items():
            if "error" in run:
                L.append(f"  {w} worker(s): {run['error']}")
                continue
            L.append(
                f"  {w} worker(s): {run['points']} points in {run['command_wall_s']:.1f} s (whole command) = "
                f"{run['points_per_s']:.1f} points/s; a point {run['mean_point_ms']:.0f} ms in its worker, of which "
                f"its loop {run['mean_loop_ms']:.0f} ms; the command {run['command_ms_per_point_per_worker']:.0f} ms "
                "per point and worker"
            )
        if "speedup_2" in sw:
            ok = "meets" if sw["speedup_2"] >= 1.8 else "MISSED"
            L.append(f"  speed-up on 2 workers: {sw['speedup_2']:.2f}x (target >= 1.8x: {ok})")
        st = sw.get("study", {})
        if "error" in st:
            L.append(f"  10^4-point study: {st['error']}")
        elif st:
            L.append(
                f"  {st['points']}-point study on {st['workers']} workers: {st['command_wall_s']:.0f} s "
                f"({st['points_per_s']:.1f} points/s)"
            )

    rl = L.sec(r, "rerun_live", "Rerun live view: 10^6 periods x 16 signals into the served (viewer-side) buffer")
    if rl:
        for key in ("decimate_1", "decimate_10"):
            d = rl[key]
            L.append(
                f"  {key.replace('_', ' ')}: {d['samples_sent']:,} samples in {d['wall_s']:.1f} s "
                f"({d['periods_per_s']:,.0f} periods/s), "
                f"RSS +{(d['rss_after_kB'] - d['rss_before_kB']) / 1024:.0f} MiB "
                f"(peak {d['peak_rss_kB'] / 1024:.0f} MiB), server memory limit {rl['server_memory_limit']}"
            )

    yc = L.sec(r, "yao2020_identification", "Yao 2020 identification vs RLS (callgrind, instructions per call)")
    if yc:
        ipc = yc["instructions_per_call"]
        for fn, label in (
            ("yao2020_identification_update", "proposed identification update"),
            ("yao2020_rls_update", "RLS baseline update (Yao 2020 Eq. 46-48)"),
            ("yao2020_dpcc_step", "whole DPCC step"),
        ):
            L.append(f"  {label + ' (' + fn + ')':<72} {ipc[fn]:8.1f}")
        L.append(
            f"  RLS / proposed: {yc['rls_over_proposed']:.1f}x  (paper on a 150 MHz DSP: 0.313 us vs 18.9 us, "
            f"{yc['paper_us_on_150MHz_DSP']['ratio']:.0f}x)"
        )

    cm = L.sec(r, "cortex_m4", "Cortex-M4F build of firmware_shim/core (arm-none-eabi-gcc)")
    if cm:
        L.append(f"  {cm['compiler']}; flags: {cm['flags']}")
        L.append(f"  {'object':<26}{'text':>8}{'data':>8}{'bss':>8}")
        for o in cm["objects"]:
            L.append(f"  {o['object']:<26}{o['text']:>8}{o['data']:>8}{o['bss']:>8}")
        tot = cm["total"]
        L.append(f"  {'total':<26}{tot['text']:>8}{tot['data']:>8}{tot['bss']:>8}")

    mc = L.sec(r, "mcu", "the drive firmware as the Cortex-M4F image in the loop (bench run --drive mcu)")
    if mc:
        img = mc["image"]
        L.append(
            f"  image: flash {img['flash_bytes']:,} B (text {img['text']:,} + data {img['data']:,}), static RAM "
            f"{img['ram_bytes']:,} B (data + bss {img['bss']:,})"
        )
        L.append(f"  {'drive':<56}{'instr/step':>11}{'max':>7}{'periods/s':>11}{'command':>9}")
        for run in mc["runs"].values():
            L.append(
                f"  {run['what']:<56}{run['instructions_mean']:>11.0f}{run['instructions_max']:>7.0f}"
                f"{run['loop_periods_per_s'] or 0:>11.0f}{run['whole_command_s'] or 0:>8.0f}s"
            )
        y = mc["yao2020_identification_vs_rls"]
        L.append(
            f"  Yao 2020 on the M4F image: identification {y['identification_instructions']:.0f}, RLS "
            f"{y['rls_instructions']:.0f} instructions per step ({y['rls_over_identification'] or 0:.1f}x); "
            f"the paper's DSP: {y['paper_identification_cycles']:.0f} vs {y['paper_rls_cycles']:.0f} cycles "
            f"({y['paper_rls_over_identification']:.0f}x)"
        )
        L.append(f"  ({mc['note']})")

    co = L.sec(r, "canopen", "CANopen frame handling (co_perf, in-process)")
    if co:
        for k, v in co.items():
            if k.endswith("_ns"):
                L.append(f"  {k[:-3]:<40} {v:8.1f} ns")


def _vcan(r: dict[str, Any], L: _Lines) -> None:
    head, err = L.head, L.err
    if "vcan" not in r:
        return
    v = r.get("vcan")
    head("lockstep over vcan0")
    if v is None:
        L.append("  skipped (--quick)")
    elif not err(v):
        L.append(
            f"  where: {v['where']} (kernel {v.get('kernel')}, {v.get('logical_cpus')} CPUs), "
            f"{v['wall_s_including_boot']:.0f} s including boot"
        )
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
        for key, label in (
            ("floor_4", "floor, 4 frames (SYNC, 2 meas, cmd)"),
            ("floor_6", "floor, 6 frames (+2 drive trace PDOs)"),
            ("floor_6_recorded", "floor, 6 frames + candump recorder"),
        ):
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
        # Same frames on the same bus: the loop without its recorder against the 6-frame floor, and the
        # recorded loop against the 6-frame floor with the same recorder.
        fl6 = (v.get("floor_6", {}) or {}).get("periods_per_s")
        unrec_rate = (v.get("lockstep_unrecorded", {}) or {}).get("periods_per_s")
        rec_ratio = (v.get("floor_6_recorded", {}) or {}).get("real_over_floor")
        same = [r for r in ((unrec_rate / fl6) if unrec_rate and fl6 else None, rec_ratio) if r is not None]
        L.append(
            f"  target real/floor of the same frames >= {TARGET_VCAN_RATIO}: "
            + (
                ", ".join(f"{x:.2f}" for x in same) + " -> " + _fmt_target(min(same) >= TARGET_VCAN_RATIO)
                if same
                else "not measured"
            )
        )
        ch = v.get("long_choice", {})
        L.append(
            f"  long run: {ch.get('periods')} periods chosen (measured rate x {ch.get('budget_s')} s budget, "
            f"target {ch.get('target_periods')})"
        )
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


def _mb(kB: float | None) -> str:
    return "?" if kB is None else f"{kB / 1024:.0f} MB"


def _num(x: float | None, unit: str) -> str:
    if x is None:
        return "-"
    if unit == "x":
        return f"{x:.3g}x"
    return f"{x:.3g} {unit}"


def _pipeline(r: dict[str, Any], L: _Lines) -> None:
    p = L.sec(r, "pipeline", "pipeline: what the user waits for, side by side (bench run, run_scenario, peer)")
    if p is None:
        return

    def part(key: str) -> dict[str, Any]:
        s = p.get(key) or {}
        if "error" in s:
            L.append(f"  {key}: ERROR {s['error']}")
            return {}
        return s

    one = part("one_second")
    if one:
        w = one["wall_s"]
        L.append(
            f"  1 s scenario ({one['periods']:,} periods), whole `bench run --bus direct --no-viewer` process: "
            f"min {w['min']:.2f} / median {w['median']:.2f} / max {w['max']:.2f} s over {w['n']} run(s), "
            f"peak RSS {_mb(one['peak_rss_kB'])}"
        )
    wh = part("whole")
    if wh:
        files = ", ".join(
            f"{k} {v / 1e6:.1f} MB" for k, v in sorted(wh["bytes"].items(), key=lambda kv: -kv[1]) if v >= 1e5
        )
        L.append(
            f"  {wh['periods']:,} periods, whole process, every output: {wh['wall_s']['median']:.2f} s "
            f"({wh['periods_per_s_whole_process']:,.0f} periods/s), peak RSS {_mb(wh['peak_rss_kB'])}, "
            f"{wh['total_bytes'] / 1e6:.0f} MB written"
        )
        L.append(f"    files: {files} (and the small ones)")
    lp = part("loop")
    if lp:
        a, b = lp["loop"], lp["loop_recorded"]
        L.append(
            f"  the loop alone (configured Session, direct, no recorder), {a['periods']:,} periods: "
            f"{a['periods_per_s']:,.0f} periods/s; with the frame recorder: {b['periods_per_s']:,.0f} "
            f"periods/s; peak RSS {_mb(lp['peak_rss_kB'])}"
        )
    for n, a in part("api").items():
        over = f" = {a['over_loop']:.3f} x the loop" if a.get("over_loop") else ""
        L.append(
            f"  run_scenario + summary + traces.npy, {int(n):,} periods: {a['api_wall_s']:.2f} s in the call "
            f"({a['periods_per_s']:,.0f} periods/s{over}), process {a['process_wall_s']:.2f} s, "
            f"peak RSS {_mb(a['peak_rss_kB'])}"
        )
    lf = part("live_follow")
    if lf:
        L.append(
            f"  VM live view, an update of ~{lf['periods_per_update']:,} periods (follow log -> decode -> "
            f"traces + .rrd): early {lf['update_ms_early_median']:.2f} ms, late {lf['update_ms_late_median']:.2f} "
            f"ms over {lf['updates']} updates ({lf['us_per_period_late']:.2f} us/period)"
        )
    g = part("gem")
    if "wall_s" in g:
        L.append(
            f"  peer {g['simulator']} ({g['solver']}, {g['speed']}), same 1 s scenario: whole process median "
            f"{g['wall_s']['median']:.2f} s over {g['repetitions']}, {g['sim_periods_per_s']:,.0f} periods/s "
            f"in its loop, peak RSS {_mb(g['peak_rss_kB'])}"
        )
        if p.get("one_second_gem_over_bench"):
            L.append(f"    1 s scenario, whole process: the bench is {p['one_second_gem_over_bench']:.1f}x faster")
    elif g:
        L.append(f"  peer gym-electric-motor: {g.get('unavailable') or g.get('skipped')}")
    rows = p.get("targets") or []
    if rows:
        L.append("")
        L.append(f"  {'target':<42}{'measured':>12}{'target':>14}{'ratio':>8}{'was':>9}  verdict")
        for t in rows:
            was = "-" if t["was"] is None else f"{t['was']:g}"
            verdict = "not judged" if t["met"] is None else ("met" if t["met"] else "NOT met")
            ratio = "-" if t["ratio"] is None else f"{t['ratio']:.2f}"
            L.append(
                f"  {t['label']:<42}{_num(t['measured'], t['unit']):>12}"
                f"{t['op'] + ' ' + _num(t['target'], t['unit']):>14}{ratio:>8}{was:>9}  {verdict}"
                + (f" ({t['note']})" if t.get("note") else "")
            )


def format_report(r: dict[str, Any]) -> str:
    L = _Lines()
    _cores(r, L)
    _pipeline(r, L)
    _vcan(r, L)
    from bench.tools.perf.soak import format_soak

    format_soak(r, L)
    L.append("")
    L.append(f"total wall time {r['wall_s']:.0f} s; JSON saved to {r.get('saved')}")
    return "\n".join(L)
