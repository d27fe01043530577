"""`bench sweep`: a study over scenario keys, run on Dask (bench/sweep/engine.py), rows streamed to
Parquet (bench/sweep/table.py), shown as heat-map, boundary line or distributions (bench/sweep/report.py)."""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench.sweep.bisect import Condition, parse_bisect, parse_condition
from bench.sweep.point import METRICS, NUMERIC
from bench.sweep.space import Space, SpaceError, build, point_id

if TYPE_CHECKING:
    from bench.sweep.engine import Engine
    from bench.sweep.table import TableWriter


def _scenario_path(text: str) -> Path:
    """The scenario argument (bench.scenario.bundled: the bench's own scenarios from any folder), imported when
    used: the module reads the EDS."""
    from bench.scenario import bundled

    return bundled(Path(text))


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", type=_scenario_path, help="the scenario every point starts from (TOML)")
    g = p.add_argument_group("the study")
    g.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="KEY=V1,V2,...|START:STOP:STEP",
        help="a key's values, listed or as a range with STOP included (repeatable: the product)",
    )
    g.add_argument(
        "--sample",
        action="append",
        default=[],
        metavar="KEY=uniform(A,B)|normal(M,S)",
        help="Monte Carlo: a key drawn --samples times (repeatable; with --grid: at every grid point)",
    )
    g.add_argument("--samples", type=int, default=None, metavar="N", help="draws per grid point for --sample")
    g.add_argument(
        "--seed",
        type=int,
        default=1,
        help="seed of the --sample draws (default 1); the ADC-noise seed is the key scenario.seed",
    )
    g.add_argument(
        "--bisect",
        default=None,
        metavar="KEY=LO:HI",
        help="search where --until changes along KEY (with --grid: at every grid point)",
    )
    g.add_argument(
        "--until",
        default=None,
        metavar="CONDITION",
        help="METRIC OP VALUE, e.g. 'status!=ok', 'error_growth_per_period>=1', 'overshoot_pct>5'",
    )
    g.add_argument(
        "--tol", type=float, default=None, help="stop the search when the bracket is narrower (default (HI-LO)/1000)"
    )
    from bench.scenario import add_set_argument  # here: the module reads the EDS, --help of other commands need not

    add_set_argument(g, "fixed overrides applied to every point")
    g.add_argument(
        "--py-law",
        default=None,
        metavar="FILE.py:CLASS",
        help="every point with a current law prototyped in Python in place of the registered law its class names "
        "(bench run --py-law; docs/YOUR_CONTROLLER.md section 10)",
    )
    r = p.add_argument_group("where it runs")
    r.add_argument(
        "--workers",
        "--jobs",
        dest="workers",
        type=int,
        default=None,
        help="worker processes of the embedded LocalCluster (default: all cores)",
    )
    r.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:8786|FILE.json",
        help="an existing Dask cluster: its scheduler's address or scheduler file (docs/SWEEPS.md)",
    )
    r.add_argument("--serial", action="store_true", help="no Dask: every point in this process, in order")
    r.add_argument("--no-dashboard", action="store_true", help="no Dask dashboard for the embedded cluster")
    r.add_argument(
        "--dashboard-address",
        default="127.0.0.1:0",
        metavar="HOST:PORT",
        help="where the embedded cluster's dashboard listens (default 127.0.0.1:0: this machine only, a free "
        "port; e.g. 0.0.0.0:8787 to show it on the network). The cluster itself listens on 127.0.0.1",
    )
    o = p.add_argument_group("outputs")
    o.add_argument("--out", type=Path, default=None, help="output folder (default runs/sweep-NAME-TIMESTAMP)")
    o.add_argument("--resume", action="store_true", help="continue the study in --out: skip its finished points")
    o.add_argument("--csv", action="store_true", help="also write sweep.csv")
    o.add_argument(
        "--metric",
        default=None,
        metavar="METRIC",
        help=f"the heat-map's / histogram's metric: {', '.join(NUMERIC)} or identified.* (default "
        "periods_to_settle; with --bisect, the --until metric)",
    )


class Refused(Exception):
    pass


def _study(args: argparse.Namespace) -> tuple[Any, str, Space, tuple[str, float, float] | None, Condition | None]:
    from bench.scenario import ScenarioError, load, loads, unselected_law

    try:
        text = args.scenario.read_text()
    except OSError as exc:
        raise Refused(f"{args.scenario}: cannot read: {exc.strerror}") from exc
    space = build(args.grid, args.sample, args.samples, args.seed)
    bis = parse_bisect(args.bisect) if args.bisect else None
    cond = parse_condition(args.until, METRICS) if args.until else None
    if bis and cond is None:
        raise SpaceError("--bisect needs --until CONDITION: what changes at the boundary")
    if cond and not bis:
        raise SpaceError("--until is the condition of --bisect KEY=LO:HI")
    if bis and space.samples:
        raise SpaceError("--bisect runs with --grid, not with --sample")
    if bis and bis[0] in space.keys:
        raise SpaceError(f"{bis[0]}: a key is given twice (--grid/--sample/--bisect)")
    if args.tol is not None and not (bis and 0 < args.tol < bis[2] - bis[1]):
        raise SpaceError("--tol is for --bisect and must be > 0 and below HI-LO")
    if args.metric is not None and args.metric not in NUMERIC and not args.metric.startswith("identified."):
        raise SpaceError(f"--metric {args.metric}: allowed {', '.join(NUMERIC)}, identified.*")
    if not space.keys and not bis:
        raise SpaceError("nothing to sweep: give --grid, --sample or --bisect")
    if args.workers is not None and args.workers < 1:
        raise SpaceError(f"--workers {args.workers}: must be >= 1")
    if args.serial and (args.scheduler or args.workers):
        raise SpaceError("--serial runs in this process: no --workers or --scheduler")
    try:
        sc = load(args.scenario, args.overrides)
        checks = space.distinct_values()
        if bis:
            checks[bis[0]] = [repr(bis[1]), repr(bis[2])]
        seen = [sc]
        for key, vals in checks.items():  # every value validated before anything starts
            for v in vals:
                point = loads(text, str(args.scenario), [*args.overrides, f"{key}={v}"])
                seen += [point] if key == "controller.controller" else []
        if (unselected := unselected_law(seen, "the study (its scenario and its points)")) is not None:
            raise ScenarioError(unselected)
        _python_law(args, sc)
    except ScenarioError as exc:
        raise Refused(str(exc)) from exc
    return sc, text, space, bis, cond


def _python_law(args: argparse.Namespace, sc: Any) -> None:
    """--py-law: its class loaded and checked here, before any point runs; the workers get FILE.py made absolute."""
    if args.py_law is None:
        return
    from bench.law_py import LawError, checked
    from bench.scenario import ScenarioError, unselected_python_law

    try:
        law = checked(None, args.py_law)
    except LawError as exc:
        raise ScenarioError(str(exc)) from None
    if (unselected := unselected_python_law(sc, law.law)) is not None:
        raise ScenarioError(unselected)
    where, _, name = args.py_law.rpartition(":")
    if where.endswith(".py"):
        args.py_law = f"{Path(where).expanduser().resolve()}:{name}"


def _spec(args: argparse.Namespace, text: str, space: Space) -> dict[str, Any]:
    return {
        "scenario": str(args.scenario),
        "scenario_sha256": hashlib.sha256(text.encode()).hexdigest(),
        "set": list(args.overrides),
        **space.spec(),
        "bisect": args.bisect,
        "until": args.until,
        "tol": args.tol,
        **({"py_law": args.py_law} if args.py_law else {}),
    }


def _prepare_out(args: argparse.Namespace, name: str, spec: dict[str, Any]) -> Path:
    from bench.sweep.table import PARTS, TABLE

    out = args.out or Path("runs") / f"sweep-{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    from bench.paths import lost_in_vm

    if (lost := lost_in_vm(out)) is not None:
        raise Refused(f"--out {lost}")
    meta = out / "sweep.json"
    has_rows = (out / TABLE).exists() or (out / PARTS).is_dir()
    if args.resume:
        if args.out is None:
            raise Refused("--resume needs --out: the folder of the study to continue")
        if not meta.exists():
            raise Refused(f"--resume: {out} holds no study (no sweep.json)")
        old = json.loads(meta.read_text()).get("study", {})
        diff = sorted(k for k in set(old) | set(spec) if old.get(k) != spec.get(k))
        if diff:
            raise Refused(
                f"--resume: {out} holds another study ({', '.join(diff)} differ); same arguments, or a new --out"
            )
    elif has_rows:
        raise Refused(f"{out} already holds a study: --resume to continue it, or another --out")
    out.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        meta.write_text(json.dumps({"study": spec, "state": "running"}, indent=2))
    return out


class Progress:
    """A bar on a terminal (points/s); otherwise a line every tenth of the work."""

    def __init__(self, total: int, what: str) -> None:
        from tqdm import tqdm

        self.tty = sys.stderr.isatty()
        self.bar = tqdm(total=total, unit="pt", desc=what, disable=not self.tty, smoothing=0.1)
        self.total, self.done, self.t0, self.next = total, 0, time.monotonic(), max(1, total // 10)

    def add(self, n: int) -> None:
        self.bar.update(n)
        self.done += n
        if not self.tty and (self.done >= self.next or self.done == self.total):
            rate = self.done / max(1e-9, time.monotonic() - self.t0)
            print(f"  {self.done}/{self.total} points, {rate:.1f} points/s", flush=True)
            self.next += max(1, self.total // 10)

    def close(self) -> None:
        self.bar.close()


def _start_engine(args: argparse.Namespace, sc: Any) -> Engine | None:
    """Where the points run (the embedded LocalCluster, an existing --scheduler, or this process with --serial),
    said on stdout with its Dask dashboard; None when --scheduler did not answer (said on stderr)."""
    from bench.sweep.engine import Engine

    try:
        engine = Engine(
            args.scheduler,
            args.workers,
            args.serial,
            dashboard=not args.no_dashboard,
            dashboard_address=args.dashboard_address,
        )
    except OSError as exc:  # no scheduler at that address, or it did not answer in time
        print(f"bench sweep: --scheduler {args.scheduler}: {exc}", file=sys.stderr)
        return None
    engine.py_law = args.py_law
    print(f"bench sweep: {sc.name} ({sc.periods} periods a point) on {engine.where}")
    if engine.dashboard:
        where = "" if args.scheduler else f" (listening on {engine.dashboard_listens}; --dashboard-address)"
        print(f"bench sweep: Dask dashboard {engine.dashboard}{where}")
    return engine


def _run_points(
    engine: Engine,
    text: str,
    args: argparse.Namespace,
    space: Space,
    done: dict[str, Any],
    out: Path,
    writer: TableWriter,
) -> tuple[list[str], int]:
    """The grid / Monte Carlo points not done yet, in batches over the workers, their rows streamed to the table
    under a progress bar: the study's point ids in order, and how many points ran now."""
    from bench.sweep.engine import batches

    points = space.points()
    order = [point_id(p) for p in points]
    todo = [p for p, pid in zip(points, order, strict=True) if pid not in done]
    if done:
        print(f"bench sweep: resuming: {len(points) - len(todo)} of {len(points)} points already in {out}")
    print(f"bench sweep: {len(todo)} points to run")
    ran = 0
    prog = Progress(len(todo), "points")
    try:
        for rows in engine.run(text, str(args.scenario), args.overrides, batches(todo, engine.workers)):
            writer.add(rows)
            ran += len(rows)
            prog.add(len(rows))
    finally:
        prog.close()
    return order, ran


def _interrupted(args: argparse.Namespace, engine: Engine, writer: TableWriter, out: Path, done: dict[str, Any]) -> int:
    """Ctrl-C: the rows run so far reach the table and the cluster stops, whatever is pressed again; says how to
    run the rest (--resume). The exit status 130."""
    from bench.stop import deferred

    with deferred():  # the rows must reach the table, and the cluster must stop, whatever is pressed
        writer.flush()
        engine.close()
    again = "--resume" + ("" if args.out else f" --out {out}")
    print(
        f"\nbench sweep: interrupted; {writer.written} new points kept in {out} ({writer.written + len(done)} "
        f"done in all); the same command with {again} runs the rest",
        file=sys.stderr,
    )
    return 130


def main(args: argparse.Namespace) -> int:
    from bench.sweep.engine import WorkerError
    from bench.sweep.table import TableWriter, read_done

    try:
        sc, text, space, bis, cond = _study(args)
        spec = _spec(args, text, space)
        out = _prepare_out(args, sc.name, spec)
    except (SpaceError, Refused) as exc:
        print(f"bench sweep: {exc}", file=sys.stderr)
        return 2
    done = {r["point_id"]: r for r in read_done(out).to_pylist()} if args.resume else {}
    engine = _start_engine(args, sc)
    if engine is None:
        return 2
    writer = TableWriter(out)
    t0 = time.monotonic()
    try:
        if bis and cond:
            from bench.sweep.bisect import run_searches

            results, order, ran = run_searches(
                engine, text, str(args.scenario), args.overrides, space, bis, cond, args.tol, done, writer
            )
        else:
            order, ran = _run_points(engine, text, args, space, done, out, writer)
            results = None
    except KeyboardInterrupt:
        return _interrupted(args, engine, writer, out, done)
    except WorkerError as exc:
        writer.flush()
        engine.close()
        print(f"bench sweep: {exc}; {writer.written} new points kept in {out} (--resume continues)", file=sys.stderr)
        return 1
    except BaseException:
        writer.flush()
        engine.close()
        raise
    wall = time.monotonic() - t0
    engine.close()
    table = writer.finish(order, args.csv)
    from bench.sweep.outputs import write_outputs

    write_outputs(out, args, sc, spec, space, table.to_pylist(), results, engine, wall, ran, len(done))
    return 0
