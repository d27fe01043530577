"""What a failing test's report and the JUnit properties show of a run. The run itself is bench.result's HilRun (what
hil_run and bench.api.run return), re-exported here for the plugin's modules."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path
from typing import Any

from bench.result import HilRun, RunFolderError, load_run
from bench.result.steps import Step, fmt

__all__ = ["HilRun", "RunFolderError", "junit_properties", "load_run", "report_text", "step_line", "viewer_command"]


def viewer_command(recording: Path) -> str:
    """`rerun FILE`: the Rerun viewer of this environment (the venv's when it is not on PATH)."""
    exe = shutil.which("rerun") or next(
        (str(p) for p in [Path(sys.executable).parent / "rerun"] if p.is_file()), "rerun"
    )
    return f"{exe} {recording}"


def step_line(s: Step) -> str:
    settle = "never settles" if s.periods_to_settle is None else f"settles in {s.periods_to_settle} periods"
    over = "n/a" if s.overshoot_pct is None else f"{fmt(s.overshoot_pct)} %"
    err = "n/a" if s.steady_state_error_A is None else f"{fmt(s.steady_state_error_A)} A"
    return f"{s.describe()}: {settle}, overshoot {over}, steady-state error {err}"


def report_text(run: HilRun) -> str:
    """What a failing test's report shows of the run: where it is, how to look at it, what it measured."""
    expected = ", a status the scenario expects" if run.status_expected else ""
    rec = "none written" if run.recording is None else f"{run.recording}\n  view it:   {viewer_command(run.recording)}"
    lines = [
        f"run folder:  {run.folder}",
        f"scenario:    {run.scenario or run.summary.get('scenario')} on bus {run.bus}",
        f"status:      {run.status} (exit status {run.exit_code}{expected})",
        *_motor_line(run.summary.get("motor")),
        f"summary:     {run.folder / 'summary.json'}",
        f"traces:      {run.folder / 'traces.npy'} (numpy.load)",
        f"plots:       {', '.join(p.name for p in sorted(run.folder.glob('*.svg'))) or 'none written'}",
        f"bus log:     {run.bus_log}",
        f"recording:   {rec}",
    ]
    lines += [f"step:        {step_line(s)}" for s in run.steps]
    return "\n".join(lines)


def _motor_line(block: Any) -> list[str]:
    """The report's line on a motor folder or FMU (summary.json "motor"); none for a built-in motor."""
    if not isinstance(block, dict) or not (block.get("folder") or block.get("fmu")):
        return []
    return [f"motor:       {block.get('folder') or block.get('fmu')} (content {block.get('digest')})"]


def junit_properties(run: HilRun, prefix: str = "hil_") -> list[tuple[str, object]]:
    """The key figures as JUnit properties (CI servers show them): status, exit code, folder, per step
    <prefix><signal>_p<period>_settle_periods / _overshoot_pct / _ss_error_A."""
    props: list[tuple[str, object]] = [
        (f"{prefix}status", run.status),
        (f"{prefix}exit_code", run.exit_code),
        (f"{prefix}run_folder", str(run.folder)),
    ]
    for s in run.steps:
        p = f"{prefix}{s.signal}_p{s.at_period}"
        props.append((f"{p}_settle_periods", "never" if s.periods_to_settle is None else s.periods_to_settle))
        props.append((f"{p}_overshoot_pct", "n/a" if s.overshoot_pct is None else f"{s.overshoot_pct:.6g}"))
        props.append((f"{p}_ss_error_A", "n/a" if s.steady_state_error_A is None else f"{s.steady_state_error_A:.6g}"))
    return props
