"""The pipeline section's measured children, each in a fresh process so that its peak RSS is its own:

    python -m bench.tools.perf.child api  --periods N --dir D   run_scenario with a sweep's outputs
    python -m bench.tools.perf.child loop --periods N           the same scenario's loop alone

Each prints one JSON line. `api` is what a sweep point costs through the Python API: the summary
(written to D/summary.json) and the traces (D/traces.npy, TraceFileSink). `loop` runs the same
configured Session twice in direct mode: without the in-process recorder (the loop's own rate,
what RunOptions(record=False) would mean; in direct mode run_scenario always records), then with
the recorder emptied after every chunk and nothing decoded (the loop plus frame capture).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path
from typing import Any

from bench.paths import REPO

SCENARIO = REPO / "scenarios" / "you2019_step.toml"


def _scenario(periods: int) -> Any:
    from bench.scenario import load

    return load(SCENARIO, [f"scenario.periods={periods}"])


def _json_default(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serializable: {type(o)}")


def api(periods: int, folder: Path) -> dict[str, Any]:
    from bench.run import RunOptions, TraceFileSink, run_scenario

    folder.mkdir(parents=True, exist_ok=True)
    sc = _scenario(periods)
    t0 = time.perf_counter()
    res = run_scenario(sc, RunOptions(bus="direct"), sinks=[TraceFileSink(folder / "traces.npy")])
    (folder / "summary.json").write_text(json.dumps(res.summary, indent=2, default=_json_default))
    wall = time.perf_counter() - t0
    timing = res.summary.get("timing", {})
    return {
        "periods": int(res.summary["periods"]),
        "status": res.status,
        "api_wall_s": wall,
        "run_wall_s": timing.get("run_wall_s"),
        "periods_per_s": res.summary["periods"] / wall,
        "run_periods_per_s": res.summary["periods"] / timing["run_wall_s"] if timing.get("run_wall_s") else None,
        "bytes": {p.name: p.stat().st_size for p in sorted(folder.iterdir())},
    }


def _session_loop(periods: int, recorded: bool) -> dict[str, Any]:
    from bench.run import DirectSource, RunOptions, Session

    opts = RunOptions(bus="direct")
    sess = Session(_scenario(periods), opts)
    frames = 0
    try:
        sess.open()
        assert sess.hil is not None and sess.direct is not None
        source = DirectSource(sess.hil, opts.chunk_periods) if recorded else None
        if source is not None:  # as run_scenario wires it: the loop's thread hands each chunk over
            sess.direct.on_chunk = source.collect
            sess.direct.on_stop = source.release
        sess.reset_nodes()
        sess.configure()
        if source is not None:
            source.drain(final=True)  # the configuration's frames

        def tick() -> None:
            nonlocal frames
            if source is not None:
                frames += len(source.drain())

        run_wall = sess.run(None, tick)
        st = sess.statuses()
    finally:
        sess.close()
    res = {
        "periods": periods,
        "run_wall_s": run_wall,
        "periods_per_s": periods / run_wall,
        "plant_missed_commands": st.get("plant.Run control.missed_commands"),
    }
    if recorded:
        res["frames"] = frames
    return res


def loop(periods: int) -> dict[str, Any]:
    _session_loop(min(periods, 20_000), recorded=False)  # warm-up: code pages, libm, the OD
    return {"loop": _session_loop(periods, recorded=False), "loop_recorded": _session_loop(periods, recorded=True)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.tools.perf.child")
    ap.add_argument("mode", choices=("api", "loop"))
    ap.add_argument("--periods", type=int, required=True)
    ap.add_argument("--dir", type=Path, default=None)
    a = ap.parse_args(argv)
    if a.mode == "api":
        if a.dir is None:
            ap.error("api needs --dir")
        out = api(a.periods, a.dir)
    else:
        out = loop(a.periods)
    out["self_peak_rss_kB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
