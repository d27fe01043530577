"""`bench reproduce`'s command: its arguments, the claims run on the bench (here, or in the VM over vcan on a
host without SocketCAN), the runs' views, the report."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
import traceback
from pathlib import Path
from typing import Any

from bench.reproduce.report import PAPERS, publish, refusal, write_reports
from bench.reproduce.views import make_views


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--paper",
        choices=[*PAPERS, "all"],
        default="all",
        help="000 = You 2019, 001 = Yao 2020, 003 = Zhao 2022, all (default)",
    )
    p.add_argument(
        "--claim",
        dest="claims",
        action="append",
        default=[],
        metavar="NAME",
        help="run only this claim function of the papers (repeatable; its name as the progress lines print it, "
        "e.g. claim_observer; a wrong name lists the papers' names)",
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


def chosen(fns: list[tuple[str, str, Any]], names: list[str]) -> tuple[list[tuple[str, str, Any]], str | None]:
    """The claim functions named by --claim (all when none is named), or why not: a name the papers lack."""
    if not names:
        return fns, None
    known = [fn.__name__ for _, _, fn in fns if not isinstance(fn, Exception)]
    unknown = [n for n in names if n not in known]
    if unknown:
        broken = [f"{name}'s claims module did not import ({fn})" for _, name, fn in fns if isinstance(fn, Exception)]
        return [], (
            f"bench reproduce: --claim {unknown[0]}: the paper(s) chosen have no claim function of that name; "
            f"nothing was run or written. Their claim functions: {', '.join(known) or 'none'}"
            + (f"; {'; '.join(broken)}" if broken else "")
        )
    return [f for f in fns if isinstance(f[2], Exception) or f[2].__name__ in names], None


def run_claim_function(fn: Any, bus: str, code: str, paper: str) -> list[dict[str, Any]]:
    """Run one claim function; its records, each with the runs whose figure shows it: the result's own
    `runs`, else the function's runs when it made one result only (several results without `runs`:
    no figure rather than another claim's). The runs kept write their decoded trace (claims.run_raw)."""
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


def collect(papers: list[str], bus: str, out: Path, names: list[str] | None = None) -> list[dict[str, Any]]:
    """Run every claim of the papers (those named in `names`) on `bus`; write claims.json; keep the runs under
    out/runs."""
    from bench import claims
    from bench.claims import ClaimResult

    claims.RUN_ROOT = out / "runs"
    claims.RUN_ROOT.mkdir(parents=True, exist_ok=True)
    results: list[dict[str, Any]] = []
    fns, _ = chosen(_load_functions(papers), names or [])
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


def _collect_in_vm(args: argparse.Namespace, out: Path) -> list[dict[str, Any]] | None:
    """The claims over a vcan the host kernel does not have: run inside the VM into `out` (its claims.json and
    runs); None when that failed (said)."""
    from bench.run.bus.vm import VmOptions, run_in_vm

    print(f"bench reproduce: host kernel has no SocketCAN; running the claims over {args.bus} inside the VM")
    cmd = [sys.executable, "-m", "bench.cli", "reproduce", "--paper", args.paper, "--bus", args.bus]
    cmd += [a for name in args.claims for a in ("--claim", name)]
    rc = run_in_vm(
        [*cmd, "--out", str(out.resolve()), "--collect-only"],
        VmOptions(timeout_s=5400, rwdirs=[out.resolve().parent]),
    )
    if rc != 0 or not (out / "claims.json").exists():
        print(f"bench reproduce: the claims run in the VM failed (status {rc})", file=sys.stderr)
        return None
    return json.loads((out / "claims.json").read_text())


def _out_folder(args: argparse.Namespace) -> tuple[Path, str | None]:
    """The report folder, and why it (or --publish) may not be written to."""
    out: Path = args.out or Path("reports") / time.strftime("%Y%m%d-%H%M%S")
    if args.out is None:  # the default folder is always a new one
        n, base = 2, out
        while out.exists():
            out, n = base.with_name(f"{base.name}-{n}"), n + 1
    if (why := refusal(out)) is not None:
        return out, (
            f"bench reproduce: {why}; nothing was changed. Give --out a new or empty folder "
            "(or remove this one yourself)."
        )
    if args.publish and (why := refusal(args.publish, replaceable_report=True)) is not None:
        return out, (
            f"bench reproduce: --publish {why}; nothing was changed. Give a new or empty folder or a previous "
            "published report."
        )
    return out, None


def main(args: argparse.Namespace) -> int:
    papers = _papers(args.paper)
    if args.collect_only:  # inside the VM, into the folder the host made
        collect(papers, args.bus, args.out or Path("reports") / time.strftime("%Y%m%d-%H%M%S"), args.claims)
        return 0
    out, why = _out_folder(args)
    why = chosen(_load_functions(papers), args.claims)[1] or why
    if args.claims and args.publish and why is None:  # a published report is the papers' whole set
        why = (
            "bench reproduce: --publish with --claim: a published report holds every claim of the papers chosen, "
            "not some of them; nothing was run or written. Publish a run without --claim."
        )
    if why is not None:
        print(why, file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    from bench.run.bus.buses import choose_bus  # vcan in the CAN box: the claims run here

    if choose_bus(args.bus).needs_own_vm():  # neither in process, nor the CAN box, nor this host's SocketCAN
        results = _collect_in_vm(args, out)
        if results is None:
            return 1
    else:
        results = collect(papers, args.bus, out, args.claims)
    failed = make_views(out)
    wall = time.monotonic() - t0
    write_reports(out, results, args.bus, wall)
    n_ok = sum(r["verdict"] == "reproduced" for r in results)
    print(f"bench reproduce: {len(results)} claims: {n_ok} reproduced, {len(results) - n_ok} differ ({wall:.0f} s)")
    for r in results:
        print(f"  {r['verdict']:<11} bench {r.get('bench_check', '?'):<5} {r['claim_id']:<28} {r['figure']}")
    if failed:
        print(
            f"bench reproduce: {failed} run(s) have no recording or figure (see above): their claims show no figure",
            file=sys.stderr,
        )
    print(f"report: {out / 'report.md'}, {out / 'report.html'}, {out / 'report.json'}")
    if args.publish:
        publish(out, args.publish)
        print(f"published: {args.publish / 'report.md'}")
    return 0
