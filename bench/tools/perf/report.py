"""`bench perf`'s report for a person: one block per section, the pipeline section as a table of
targets (measured, target, ratio, met)."""

from __future__ import annotations

from typing import Any

from bench.tools.perf.common import TARGET_LOOP_MPS, TARGET_PLANT_MPS
from bench.tools.perf.report_vcan import format_vcan


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


def _machine(r: dict[str, Any], L: _Lines) -> None:
    """The machine the numbers were measured on (CPU, kernel, compilers, Python) and the command run."""
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


def _plant_core(r: dict[str, Any], L: _Lines) -> None:
    """The plant's C core alone (plant_perf): a table of periods/s per option set against its target."""
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


def _motor_models(r: dict[str, Any], L: _Lines) -> None:
    """The whole `bench run` with each machine model (bench/tools/perf/motors.py), interleaved rounds."""
    p = L.sec(r, "motor_models", "machine models: the linear plant, a flux map, an FMU (whole bench run, direct)")
    if p:
        L.append(f"  {p['scenario']}, {p['periods']:,} periods, {p['rounds']} interleaved rounds (medians)")
        L.append(f"  {'model':<48}{'loop us/period':>16}{'whole command s':>17}")
        for name, m in p["models"].items():
            L.append(f"  {name:<48}{m['median_loop_us_per_period']:>16.3f}{m['median_wall_s']:>17.2f}")


def _closed_loop(r: dict[str, Any], L: _Lines) -> None:
    """Plant and controller in one process: the bare cores and direct mode against the loop target, then
    direct mode's resident memory over 2 x 10^6 periods."""
    cl = L.sec(r, "closed_loop", f"plant + controller in-process (target >= {TARGET_LOOP_MPS:.0f} M periods/s)")
    if cl:
        b, d = cl["bare_cores"], cl["direct_mode"]
        L.append(
            f"  bare cores (hil_core_loop_ns)        {b['ns_per_period']:8.1f} ns/period  "
            f"{b['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(b['meets_target'])}"
            f"  (iq at end {b['iq_end_A']:.4f} A for 1 A)"
        )
        rows = [("direct mode, the bare cores' plant", cl.get("direct_mode_bare_plant"))]
        for label, x in [*rows, ("direct mode, EDS defaults", d)]:
            if x is None:
                continue
            L.append(
                f"  {label:<37}{x['ns_per_period']:8.1f} ns/period  "
                f"{x['Mperiods_per_s']:6.2f} M periods/s  {_fmt_target(x['meets_target'])}"
                f"  ({x['periods']} periods, {x.get('frames_per_period', 0):.1f} frames each, "
                f"missed commands {x['plant_missed_commands']})"
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


def _firmware(r: dict[str, Any], L: _Lines) -> None:
    """The drive firmware's core on the host (drive_perf): ns per step, then callgrind's instructions per step."""
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


def _sweep_scaling(r: dict[str, Any], L: _Lines) -> None:
    """bench sweep on Dask: points/s per worker count, the speed-up on 2 workers, the 10^4-point study."""
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


def _rerun_live(r: dict[str, Any], L: _Lines) -> None:
    """The Rerun live view: 10^6 periods into the served buffer, at decimation 1 and 10 (rate, memory)."""
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


def _yao2020(r: dict[str, Any], L: _Lines) -> None:
    """Yao 2020's identification against its RLS baseline: callgrind instructions per call, and the paper's ratio."""
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


def _cortex_m4(r: dict[str, Any], L: _Lines) -> None:
    """The Cortex-M4F build of the firmware core: compiler, flags and a size table per object."""
    cm = L.sec(r, "cortex_m4", "Cortex-M4F build of firmware_shim/core and laws/ (arm-none-eabi-gcc)")
    if cm:
        L.append(f"  {cm['compiler']}; flags: {cm['flags']}")
        L.append(f"  {'object':<26}{'text':>8}{'data':>8}{'bss':>8}")
        for o in cm["objects"]:
            L.append(f"  {o['object']:<26}{o['text']:>8}{o['data']:>8}{o['bss']:>8}")
        tot = cm["total"]
        L.append(f"  {'total':<26}{tot['text']:>8}{tot['data']:>8}{tot['bss']:>8}")


def _mcu(r: dict[str, Any], L: _Lines) -> None:
    """The firmware as the Cortex-M4F image in the loop: image size, instructions per step and rate per drive,
    Yao 2020's identification against RLS on the image."""
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


def _canopen(r: dict[str, Any], L: _Lines) -> None:
    """The CANopen stack's frame handling in-process (co_perf): ns per kind of frame."""
    co = L.sec(r, "canopen", "CANopen frame handling (co_perf, in-process)")
    if co:
        for k, v in co.items():
            if k.endswith("_ns"):
                L.append(f"  {k[:-3]:<40} {v:8.1f} ns")


def _cores(r: dict[str, Any], L: _Lines) -> None:
    """The sections measured on this machine's cores and images, in the report's order."""
    for section in (
        _machine,
        _plant_core,
        _motor_models,
        _closed_loop,
        _firmware,
        _sweep_scaling,
        _rerun_live,
        _yao2020,
        _cortex_m4,
        _mcu,
        _canopen,
    ):
        section(r, L)


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
    format_vcan(r, L)
    from bench.tools.perf.box import format_box

    format_box(r, L)
    from bench.tools.perf.soak import format_soak

    format_soak(r, L)
    from bench.tools.perf.report_realtime import format_realtime

    format_realtime(r, L)
    L.append("")
    L.append(f"total wall time {r['wall_s']:.0f} s; JSON saved to {r.get('saved')}")
    return "\n".join(L)
