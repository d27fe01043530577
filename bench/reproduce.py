"""`bench reproduce`: every quantitative claim of the three papers, run on the bench, in one report.

    bench reproduce --paper all --bus vcan0 --out reports/latest

For each claim: what the paper states (figure/table), what the bench measured, the
tolerance, the verdict (reproduced / differs) and why it differs where it does, with a
plot of the run and a link to its Rerun recording. Writes report.md, report.html and
report.json (one record per claim, for tools). Over vcan by default: on a host without
SocketCAN the claims run inside the VM (one boot) and the report is built on the host.
"""

from __future__ import annotations

import argparse
import html
import importlib
import json
import shutil
import sys
import time
import traceback
from pathlib import Path
from typing import Any

PAPERS = {
    "000": (
        "You 2019",
        "bench.claims.you2019",
        "You, Huang, Yang - Online Current Loop Tuning for PMSM Servo Drives with Deadbeat Current Control "
        "(Energies, 2019)",
    ),
    "001": (
        "Yao 2020",
        "bench.claims.yao2020",
        "Yao, Huang, Peng, Dong, Zhang - An Improved Deadbeat Predictive Current Control With Online Parameter "
        "Identification for Surface-Mounted PMSMs (IEEE TIE, 2020)",
    ),
    "003": (
        "Zhao 2022",
        "bench.claims.zhao2022",
        "Zhao, Chen, Wang, Li, Mao, Li, Zhang, Wu - An Improved Deadbeat Current Controller of PMSM Based on "
        "Bilinear Discretization (Machines, 2022)",
    ),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--paper",
        choices=[*PAPERS, "all"],
        default="all",
        help="000 = You 2019, 001 = Yao 2020, 003 = Zhao 2022, all (default)",
    )
    p.add_argument("--bus", default="vcan0", help="vcan0 (default; the VM supplies it if needed) or direct")
    p.add_argument("--out", type=Path, default=None, help="report folder (default reports/TIMESTAMP)")
    p.add_argument(
        "--publish",
        type=Path,
        default=None,
        help="also write a light copy (reports + plots, no recordings) to this folder, e.g. docs/reproduce",
    )
    p.add_argument("--collect-only", action="store_true", help=argparse.SUPPRESS)


def _papers(sel: str) -> list[str]:
    return list(PAPERS) if sel == "all" else [sel]


def _load_functions(papers: list[str]) -> list[tuple[str, str, Any]]:
    """(paper code, paper name, claim function or the import error) for every claim function of the papers."""
    fns: list[tuple[str, str, Any]] = []
    for code in papers:
        name, modname, _ = PAPERS[code]
        try:
            fns += [(code, name, fn) for fn in importlib.import_module(modname).ALL]
        except (ImportError, AttributeError) as exc:
            fns.append((code, name, exc))
    return fns


def run_claim_function(fn: Any, bus: str, code: str, paper: str) -> list[dict[str, Any]]:
    """Run one claim function; its records, each with the runs whose figure shows it: the result's own
    `runs`, else the function's runs when it made one result only (several results without `runs`:
    no figure rather than another claim's)."""
    from bench import claims
    from bench.claims import ClaimResult

    claims.RUNS_USED.clear()
    t0 = time.monotonic()
    try:
        res = fn(bus)
        recs = [r.to_dict() for r in (res if isinstance(res, list) else [res])]
    except Exception as exc:  # noqa: BLE001 - a claim that crashes is reported, not hidden
        traceback.print_exc()
        recs = [
            ClaimResult(
                paper,
                f"{code}-{fn.__name__}",
                "-",
                (fn.__doc__ or fn.__name__).strip(),
                None,
                f"error: {exc}",
                "-",
                False,
                why_differs="the bench failed to run this claim",
            ).to_dict()
        ]
    for r in recs:
        if r.get("runs") is None:
            r["runs"] = list(claims.RUNS_USED) if len(recs) == 1 else []
        r["wall_s"] = time.monotonic() - t0
        r["paper_code"] = code
    return recs


def _dur(s: float) -> str:
    return f"{s:.0f} s" if s < 90 else f"{s / 60:.0f} min"


def collect(papers: list[str], bus: str, out: Path) -> list[dict[str, Any]]:
    """Run every claim of the papers on `bus`; write claims.json; keep the runs under out/runs."""
    from bench import claims
    from bench.claims import ClaimResult

    claims.RUN_ROOT = out / "runs"
    claims.RUN_ROOT.mkdir(parents=True, exist_ok=True)
    results: list[dict[str, Any]] = []
    fns = _load_functions(papers)
    t0 = time.monotonic()
    for i, (code, name, fn) in enumerate(fns):
        if isinstance(fn, Exception):
            results.append(
                ClaimResult(
                    name,
                    f"{code}-missing",
                    "-",
                    "the bench has no claims module for this paper",
                    None,
                    f"{fn}",
                    "-",
                    False,
                    why_differs="not implemented",
                ).to_dict()
            )
            continue
        el = time.monotonic() - t0
        eta = f", ~{_dur(el / i * (len(fns) - i))} left" if i else ""
        print(f"reproduce [{i + 1}/{len(fns)}] {name}: {fn.__name__} ... ({_dur(el)} elapsed{eta})", flush=True)
        results.extend(run_claim_function(fn, bus, code, name))
    print(f"reproduce: {len(fns)} claim functions, {len(results)} claims in {_dur(time.monotonic() - t0)}", flush=True)
    (out / "claims.json").write_text(json.dumps(results, indent=2, default=str))
    return results


def _overview_plot(run: Path, tr: dict[str, Any], title: str) -> Path | None:
    """The currents against their references around the first reference steps, and the voltage commands."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n = len(tr.get("period", ()))
    if n == 0 or not all(c in tr for c in ("iq_A", "iq_ref_A", "id_A", "id_ref_A", "vd_V", "vq_V")):
        return None
    tr = dict(tr)
    if "drive_iq_ref_active_A" in tr and not np.any(tr["iq_ref_A"]):
        tr["iq_ref_A"] = np.nan_to_num(tr["drive_iq_ref_active_A"])  # speed/position mode: the loop's own iq*
    changes = np.nonzero(np.abs(np.diff(tr["iq_ref_A"])) + np.abs(np.diff(tr["id_ref_A"])) > 1e-9)[0]
    lo = max(0, int(changes[0]) - 5) if len(changes) else 0
    hi = min(n, lo + (100 if len(changes) <= 8 else 400))
    k = tr["period"][lo:hi]
    fig = Figure(figsize=(7, 4.2))
    fig.subplots_adjust(left=0.1, right=0.97, top=0.92, bottom=0.11, hspace=0.12)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    a1.plot(k, tr["iq_ref_A"][lo:hi], "k", lw=1, drawstyle="steps-post", label="iq*")
    a1.plot(k, tr["iq_A"][lo:hi], ".-", ms=2, lw=0.8, label="iq")
    if np.nanmax(np.abs(tr["id_ref_A"][lo:hi])) > 0 or np.nanmax(np.abs(tr["id_A"][lo:hi])) > 0.05:
        a1.plot(k, tr["id_ref_A"][lo:hi], "k--", lw=0.8, drawstyle="steps-post", label="id*")
        a1.plot(k, tr["id_A"][lo:hi], ".-", ms=2, lw=0.8, label="id")
    a1.set_ylabel("A")
    a1.legend(loc="best", fontsize=7)
    a1.grid(alpha=0.3)
    a1.set_title(title, fontsize=9)
    a2.plot(k, tr["vq_V"][lo:hi], lw=0.8, label="vq*")
    a2.plot(k, tr["vd_V"][lo:hi], lw=0.8, label="vd*")
    a2.set_ylabel("V")
    a2.set_xlabel("control period")
    a2.legend(loc="best", fontsize=7)
    a2.grid(alpha=0.3)
    FigureCanvasAgg(fig)
    path = run / "overview.png"
    fig.savefig(path, dpi=80)
    return path


def postprocess_runs(out: Path) -> int:
    """Every kept run's CAN log (out/runs/NAME/bus.log, from this host or the VM) through the run pipeline:
    its Rerun recording (run.rrd) and overview figure. Runs that already have run.rrd are left as they are.
    Returns the number of runs that could not be post-processed (each reported)."""
    from bench.run.pipeline import replay_log
    from bench.view.rerun_sink import RerunSink

    root = out / "runs"
    todo = (
        [r for r in sorted(root.iterdir()) if (r / "bus.log").exists() and not (r / "run.rrd").exists()]
        if root.exists()
        else []
    )
    failed = 0
    for i, run in enumerate(todo):
        t0 = time.monotonic()
        sink = RerunSink(run.name, run / "run.rrd")
        try:
            res = replay_log(run / "bus.log", sinks=[sink], keep_trace=True)
            fig = _overview_plot(run, res.trace or {}, run.name)
            note = "" if fig is not None else ", no figure (no current trace)"
        except Exception as exc:  # noqa: BLE001 - one bad log costs its figure, not the report
            failed += 1
            note = f", FAILED: {type(exc).__name__}: {exc}"
        finally:
            sink.close()
        print(f"postprocess [{i + 1}/{len(todo)}] {run.name} ({time.monotonic() - t0:.1f} s{note})", flush=True)
    return failed


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k}: {_fmt(x)}" for k, x in v.items())
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v[:8]) + (", ..." if len(v) > 8 else "") + "]"
    return str(v)


def write_reports(out: Path, results: list[dict[str, Any]], bus: str, wall_s: float, links: bool = True) -> None:
    records = [
        {
            k: r.get(k)
            for k in (
                "paper",
                "claim_id",
                "figure",
                "statement",
                "paper_value",
                "bench_value",
                "tolerance",
                "verdict",
                "bench_check",
                "why_differs",
                "runs",
            )
        }
        for r in results
    ]
    (out / "report.json").write_text(
        json.dumps({"bus": bus, "wall_s": wall_s, "claims": records}, indent=2, default=str)
    )
    n_ok = sum(r["verdict"] == "reproduced" for r in results)
    md = [
        "# Reproduction report",
        "",
        f"Bus: `{bus}`. {len(results)} claims: {n_ok} reproduced, {len(results) - n_ok} differ. "
        f"Wall time {wall_s:.0f} s. Generated by `bench reproduce`.",
        "",
        "`verdict` compares the bench with the paper's statement; `bench check` says whether the loop behaves "
        "as the equations predict (where the paper has a typo or an approximation, the bench's derived value).",
        "",
        "| paper | claim | figure | verdict | bench check | bench value |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        md.append(
            f"| {r['paper']} | {r['claim_id']} | {r['figure']} | **{r['verdict']}** | {r.get('bench_check')} | "
            f"{_fmt(r['bench_value']).replace('|', '/')[:160]} |"
        )
    for code, (name, _, full) in PAPERS.items():
        rs = [r for r in results if r.get("paper_code") == code]
        if not rs:
            continue
        md += ["", f"## {name}", "", full, ""]
        for r in rs:
            md += [
                f"### {r['claim_id']}: {r['verdict']}",
                "",
                f"*Paper ({r['figure']}):* {r['statement']}",
                "",
                f"- paper: {_fmt(r['paper_value'])}",
                f"- bench: {_fmt(r['bench_value'])}",
                f"- tolerance: {r['tolerance']}",
            ]
            if r.get("why_differs"):
                md.append(f"- why it differs / note: {r['why_differs']}")
            shown, others = _figure_runs(out, r)
            if shown:
                md += ["", f"![{shown}](runs/{shown}/overview.png)"]
                md.append(
                    f"Run `{shown}`: [Rerun recording](runs/{shown}/run.rrd), [CAN log](runs/{shown}/bus.log), "
                    f"[summary](runs/{shown}/summary.json)"
                    if links
                    else f"Run `{shown}` (its Rerun recording and CAN log are written by `bench reproduce`)"
                )
            if others:
                md += [
                    "",
                    "Other runs of this claim: "
                    + ", ".join(
                        f"[`{o}`](runs/{o}/overview.png)" if (out / "runs" / o / "overview.png").exists() else f"`{o}`"
                        for o in others
                    ),
                ]
            md.append("")
    (out / "report.md").write_text("\n".join(md) + "\n")
    _write_html(out, results, bus, wall_s, n_ok, links)


def _figure_runs(out: Path, r: dict[str, Any]) -> tuple[str | None, list[str]]:
    """The run whose figure a claim's section shows (its first run with one) and its other runs."""
    runs = list(r.get("runs") or [])
    shown = next((run for run in runs if (out / "runs" / run / "overview.png").exists()), None)
    return shown, [run for run in runs if run != shown]


def _refusal(path: Path, replaceable_report: bool = False) -> str | None:
    """Why `path` may not be written to: an existing non-empty folder (or a file). A previous report
    folder (report.json in it) may be replaced when `replaceable_report`."""
    from bench.paths import lost_in_vm

    if (lost := lost_in_vm(path)) is not None:
        return lost
    if not path.exists():
        return None
    if not path.is_dir():
        return f"{path} exists and is not a folder"
    if not any(path.iterdir()) or (replaceable_report and (path / "report.json").exists()):
        return None
    return f"{path} exists and is not empty" + ("" if not replaceable_report else " (and holds no report.json)")


def publish(out: Path, dest: Path) -> None:
    """A light copy of a report for the repository: the reports and the plots, without the
    recordings and logs (which `bench reproduce` regenerates). Replaces `dest` only when it is
    empty or a previous report."""
    if (why := _refusal(dest, replaceable_report=True)) is not None:
        raise FileExistsError(f"not publishing: {why}")
    data = json.loads((out / "report.json").read_text())
    results = json.loads((out / "claims.json").read_text())
    shutil.rmtree(dest, ignore_errors=True)
    for png in (out / "runs").glob("*/overview.png"):
        target = dest / "runs" / png.parent.name / "overview.png"
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(png, target)
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy(out / "claims.json", dest / "claims.json")
    write_reports(dest, results, data["bus"], data["wall_s"], links=False)


def _write_html(
    out: Path, results: list[dict[str, Any]], bus: str, wall_s: float, n_ok: int, links: bool = True
) -> None:
    e = html.escape
    rows = "".join(
        f"<tr class='{e(r['verdict'])}'><td>{e(r['paper'])}</td><td><a href='#{e(r['claim_id'])}'>"
        f"{e(r['claim_id'])}</a></td><td>{e(str(r['figure']))}</td><td>{e(r['verdict'])}</td>"
        f"<td>{e(str(r.get('bench_check')))}</td></tr>"
        for r in results
    )
    sections = []
    for code, (name, _, full) in PAPERS.items():
        rs = [r for r in results if r.get("paper_code") == code]
        if not rs:
            continue
        parts = [f"<h2>{e(name)}</h2><p>{e(full)}</p>"]
        for r in rs:
            img = ""
            shown, others = _figure_runs(out, r)
            if shown:
                rec = (
                    (
                        f": <a href='runs/{e(shown)}/run.rrd'>Rerun recording</a>, "
                        f"<a href='runs/{e(shown)}/bus.log'>CAN log</a>"
                    )
                    if links
                    else ""
                )
                img = (
                    f"<figure><img src='runs/{e(shown)}/overview.png' alt='{e(shown)}'>"
                    f"<figcaption>bench run <code>{e(shown)}</code> for {e(str(r['figure']))}{rec}"
                    f"</figcaption></figure>"
                )
            if others:
                img += (
                    "<p>Other runs of this claim: "
                    + ", ".join(
                        f"<a href='runs/{e(o)}/overview.png'><code>{e(o)}</code></a>"
                        if (out / "runs" / o / "overview.png").exists()
                        else f"<code>{e(o)}</code>"
                        for o in others
                    )
                    + "</p>"
                )
            why = f"<p><b>Why it differs / note:</b> {e(r['why_differs'])}</p>" if r.get("why_differs") else ""
            parts.append(
                f"<section id='{e(r['claim_id'])}' class='{e(r['verdict'])}'><h3>{e(r['claim_id'])}: "
                f"{e(r['verdict'])}</h3><p><i>Paper ({e(str(r['figure']))}):</i> {e(r['statement'])}</p>"
                f"<ul><li>paper: {e(_fmt(r['paper_value']))}</li><li>bench: {e(_fmt(r['bench_value']))}</li>"
                f"<li>tolerance: {e(str(r['tolerance']))}</li></ul>{why}{img}</section>"
            )
        sections.append("".join(parts))
    doc = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Reproduction report</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto;}} table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:2px 6px}} tr.differs td, section.differs h3{{color:#a40}}
tr.reproduced td, section.reproduced h3{{color:#070}} img{{max-width:100%}}</style></head>
<body data-claims="{len(results)}">
<h1>Reproduction report</h1>
<p>Bus <code>{e(bus)}</code>: {len(results)} claims, {n_ok} reproduced, {len(results) - n_ok} differ;
wall time {wall_s:.0f} s. Generated by <code>bench reproduce</code>.</p>
<table><tr><th>paper</th><th>claim</th><th>figure</th><th>verdict</th><th>bench check</th></tr>{rows}</table>
{"".join(sections)}
<script>
window.addEventListener('load', function () {{
  var imgs = document.images, broken = 0;
  for (var i = 0; i < imgs.length; i++) if (!imgs[i].complete || imgs[i].naturalWidth === 0) broken++;
  document.body.setAttribute('data-images', imgs.length);
  document.body.setAttribute('data-broken-images', broken);
}});
</script>
</body></html>
"""
    (out / "report.html").write_text(doc)


def main(args: argparse.Namespace) -> int:
    from bench.canbus import host_has_vcan

    out: Path = args.out or Path("reports") / time.strftime("%Y%m%d-%H%M%S")
    papers = _papers(args.paper)
    if args.collect_only:  # inside the VM, into the folder the host made
        collect(papers, args.bus, out)
        return 0
    if args.out is None:  # the default folder is always a new one
        n, base = 2, out
        while out.exists():
            out, n = base.with_name(f"{base.name}-{n}"), n + 1
    if (why := _refusal(out)) is not None:
        print(
            f"bench reproduce: {why}; nothing was changed. Give --out a new or empty folder "
            "(or remove this one yourself).",
            file=sys.stderr,
        )
        return 2
    if args.publish and (why := _refusal(args.publish, replaceable_report=True)) is not None:
        print(
            f"bench reproduce: --publish {why}; nothing was changed. Give a new or empty folder or a previous "
            "published report.",
            file=sys.stderr,
        )
        return 2
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    if args.bus != "direct" and not host_has_vcan(args.bus):
        from bench.run.bus.vm import VmOptions, run_in_vm

        print(f"bench reproduce: host kernel has no SocketCAN; running the claims over {args.bus} inside the VM")
        rc = run_in_vm(
            [
                sys.executable,
                "-m",
                "bench.cli",
                "reproduce",
                "--paper",
                args.paper,
                "--bus",
                args.bus,
                "--out",
                str(out.resolve()),
                "--collect-only",
            ],
            VmOptions(timeout_s=5400, rwdirs=[out.resolve().parent]),
        )
        if rc != 0 or not (out / "claims.json").exists():
            print(f"bench reproduce: the claims run in the VM failed (status {rc})", file=sys.stderr)
            return 1
        results = json.loads((out / "claims.json").read_text())
    else:
        results = collect(papers, args.bus, out)
    failed = postprocess_runs(out)
    wall = time.monotonic() - t0
    write_reports(out, results, args.bus, wall)
    n_ok = sum(r["verdict"] == "reproduced" for r in results)
    print(f"bench reproduce: {len(results)} claims: {n_ok} reproduced, {len(results) - n_ok} differ ({wall:.0f} s)")
    for r in results:
        print(f"  {r['verdict']:<11} bench {r.get('bench_check', '?'):<5} {r['claim_id']:<28} {r['figure']}")
    if failed:
        print(
            f"bench reproduce: {failed} run(s) could not be post-processed (see above): their claims have no figure",
            file=sys.stderr,
        )
    print(f"report: {out / 'report.md'}, {out / 'report.html'}, {out / 'report.json'}")
    if args.publish:
        publish(out, args.publish)
        print(f"published: {args.publish / 'report.md'}")
    return 0
