"""The CAN box as a user meets it (issue 38): whole commands on a host without kernel CAN, the box against a VM
per run (BENCH_BOX=0, the way before the box) and direct mode, interleaved in one sitting.

- the box's boot (`bench box up` from down), and `bench vm -- true` (a VM per run's floor: boot, vcan0, off);
- `bench run scenarios/you2019_step.toml --bus vcan0` (200 periods) with the box up, in a VM of its own, direct;
- `bench demo --no-viewer` (800 periods over vcan0) with the box up and in a VM of its own;
- one vcan test through the pytest plugin in a project of the user's (hil_run, --hil-bus vcan0), box up and not.

Each figure: the whole process as a user runs it (bench.tools.perf.common.measure), beside the loop's own time
from the run's summary ("timing": run_wall_s, the periods and their decoding). Nothing here is asserted."""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

from bench.paths import REPO
from bench.tools.perf.common import Measured, measure

STEP = REPO / "scenarios" / "you2019_step.toml"
PLUGIN_TEST = f"""
def test_step_over_the_bus(hil_run):
    run = hil_run({str(STEP)!r})
    run.expect_status("ok")
"""


def _bench(*args: str) -> list[str]:
    return [sys.executable, "-m", "bench.cli", *args]


def _env(box: bool) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "BENCH_BOX"}
    if not box:
        env["BENCH_BOX"] = "0"  # the way before the box: a VM per run, the bench's Python inside it
    return env


def _loop_s(out: Path) -> float | None:
    try:
        return float(json.loads((out / "summary.json").read_text())["timing"]["run_wall_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _one(argv: list[str], box: bool, out: Path | None, what: str, timeout: float = 900.0) -> dict[str, Any]:
    m: Measured = measure(argv, timeout=timeout, env=_env(box), cwd=REPO).check(what)
    rec: dict[str, Any] = {"wall_s": round(m.wall_s, 2)}
    if out is not None:
        rec["loop_s"] = _loop_s(out)
    return rec


def _run(td: Path, tag: str, bus: str, box: bool) -> dict[str, Any]:
    out = td / tag
    argv = _bench("run", str(STEP), "--bus", bus, "--no-viewer", "--out", str(out))
    return _one(argv, box, out, f"bench run --bus {bus} ({tag})")


def _demo(td: Path, tag: str, box: bool) -> dict[str, Any]:
    out = td / tag
    return _one(_bench("demo", "--no-viewer", "--out", str(out)), box, out, f"bench demo ({tag})")


def _plugin(td: Path, tag: str, box: bool) -> dict[str, Any]:
    proj = td / f"project-{tag}"
    proj.mkdir()
    (proj / "test_motor.py").write_text(PLUGIN_TEST)
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--hil-bus", "vcan0"]
    argv += ["--hil-out", str(proj / "runs"), str(proj)]
    rec = _one(argv, box, None, f"pytest with the plugin ({tag})")
    found = list((proj / "runs").rglob("summary.json"))
    rec["loop_s"] = _loop_s(found[0].parent) if found else None
    return rec


def box(args: Any) -> dict[str, Any]:
    """The section; `args.repetitions` runs of each box figure (default 3), one of each VM-per-run figure."""
    from bench.run import box_down, box_info

    reps = max(1, getattr(args, "repetitions", None) or 3)
    res: dict[str, Any] = {"repetitions": reps, "runs": {"box": [], "vm_per_run": [], "direct": []}}
    res["demo"] = {"box": [], "vm_per_run": []}
    res["plugin"] = {"box": [], "vm_per_run": []}
    box_down()
    with tempfile.TemporaryDirectory(prefix="bench-perf-box-", dir=REPO / "build") as tmp:
        td = Path(tmp)  # under the repository: a folder the VM of a run of its own shares
        res["vm_true_s"] = round(measure(_bench("vm", "--", "true"), timeout=900, cwd=REPO).check("bench vm").wall_s, 2)
        res["box_boot_s"] = round(measure(_bench("box", "up"), timeout=900, cwd=REPO).check("bench box up").wall_s, 2)
        info = box_info()
        res["box_booted_s"] = info.booted_s if info is not None else None
        for i in range(reps):  # interleaved: box, direct, and (first pass) a VM per run, then the next pass
            res["runs"]["box"].append(_run(td, f"box{i}", "vcan0", True))
            res["runs"]["direct"].append(_run(td, f"direct{i}", "direct", True))
            res["demo"]["box"].append(_demo(td, f"demo-box{i}", True))
            res["plugin"]["box"].append(_plugin(td, f"box{i}", True))
            if i == 0:
                res["runs"]["vm_per_run"].append(_run(td, "vm0", "vcan0", False))
                res["demo"]["vm_per_run"].append(_demo(td, "demo-vm0", False))
                res["plugin"]["vm_per_run"].append(_plugin(td, "vm0", False))
    box_down()
    return res


def format_box(r: dict[str, Any], L: Any) -> None:
    s = L.sec(r, "box", "CAN box (issue 38): whole commands on a host without kernel CAN")
    if not s:
        return

    def fig(recs: list[dict[str, Any]]) -> str:
        if not recs:
            return "-"
        walls = sorted(x["wall_s"] for x in recs)
        loops = [x["loop_s"] for x in recs if x.get("loop_s") is not None]
        text = f"{walls[len(walls) // 2]:.1f} s" + (
            f" ({walls[0]:.1f}-{walls[-1]:.1f}, {len(walls)} runs)" if len(walls) > 1 else ""
        )
        return text + (f", loop {sorted(loops)[len(loops) // 2]:.2f} s" if loops else "")

    L.append(f"  box boot (bench box up from down): {s['box_boot_s']:.1f} s (ready after {s['box_booted_s']} s)")
    L.append(f"  bench vm -- true (a VM per run's floor): {s['vm_true_s']:.1f} s")
    L.append(f"  {'':<44}{'box up':<32}{'a VM per run (BENCH_BOX=0)':<32}direct")
    rows = (("bench run you2019_step --bus vcan0 (200 p.)", "runs"), ("bench demo --no-viewer (800 p.)", "demo"))
    for title, key in rows:
        d = s[key]
        L.append(f"  {title:<44}{fig(d['box']):<32}{fig(d['vm_per_run']):<32}{fig(d.get('direct', []))}")
    p = s["plugin"]
    L.append(f"  {'one vcan test through the plugin (pytest)':<44}{fig(p['box']):<32}{fig(p['vm_per_run'])}")
