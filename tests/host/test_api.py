"""bench.api.run, the bench as a library: a direct run in the caller's process is `bench run --bus direct` bit for bit
(its traces in memory without out=, the command's files with it), over the three papers' scenarios and a fault
scenario; a dict, a file and a Scenario with overrides are the same run; bad input is refused naming the field, with
nothing written; a run with a law of another build goes to a process of its own and reads the same."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.api import RunRefused, ScenarioError, in_process, run
from bench.paths import REPO
from bench.scenario import load

SCENARIOS = [
    "scenarios/you2019_step.toml",  # You 2019, the deadbeat step
    "scenarios/yao2020_identification.toml",  # Yao 2020, the R/L identification
    "scenarios/zhao2022_stability.toml",  # Zhao 2022, a stability point
    "scenarios/faults/you2019_drop_command.toml",  # the fault injector
]
LAW = REPO / "examples" / "laws" / "complex_vector_pi"


def _summary(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary but for its wall-clock figures and its list of files (a run without files has none)."""
    return {k: v for k, v in summary.items() if k not in ("timing", "files")}


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, int]]:
    """Each scenario once as `bench run --bus direct` (a process of its own): its folder and exit status."""
    base = tmp_path_factory.mktemp("cli")
    out = {}
    for s in SCENARIOS:
        folder = base / Path(s).stem
        out[s] = folder, bench_cli("run", REPO / s, "--bus", "direct", "--no-viewer", "--out", folder).returncode
    return out


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[Path(s).stem for s in SCENARIOS])
def test_a_run_in_memory_is_bench_run_bit_for_bit(scenario: str, cli_runs: dict[str, tuple[Path, int]]) -> None:
    folder, code = cli_runs[scenario]
    on_file = np.load(folder / "traces.npy")
    written = json.loads((folder / "summary.json").read_text())
    for _ in range(2):  # the process's second run of it: nothing carried over
        r = run(REPO / scenario)
        assert r.folder is None and r.bus_log is None and r.bus == "direct"
        assert r.traces.dtype == on_file.dtype and r.traces.tobytes() == on_file.tobytes()
        assert _summary(r.summary) == _summary(written)
        assert (r.status, r.exit_code) == (written["status"], code)
        assert [s.at_period for s in r.steps] == [s["at_period"] for s in written["steps"]]


def test_a_run_with_out_writes_bench_runs_files(tmp_path: Path, cli_runs: dict[str, tuple[Path, int]]) -> None:
    scenario = SCENARIOS[0]
    cli = cli_runs[scenario][0]
    r = run(REPO / scenario, out=tmp_path / "api")
    assert r.folder == tmp_path / "api" and r.bus_log is not None
    assert sorted(p.name for p in r.folder.iterdir()) == sorted(p.name for p in cli.iterdir())
    for name in ("traces.npy", "bus.log"):
        assert (r.folder / name).read_bytes() == (cli / name).read_bytes(), name
    assert _summary(json.loads((r.folder / "summary.json").read_text())) == _summary(
        json.loads((cli / "summary.json").read_text())
    )
    assert "bench run:" in r.stdout  # the command's own lines, captured, not on the caller's terminal
    with pytest.raises(RunRefused, match="exists and is not an empty folder"):
        run(REPO / scenario, out=tmp_path / "api")


def test_a_dict_a_file_and_a_scenario_with_overrides_are_one_run(tmp_path: Path) -> None:
    path = REPO / SCENARIOS[0]
    sets = {"scenario.periods": 120, "controller.L_hat_ratio": 0.5}
    from_file = run(path, sets)
    table = tomllib.loads(path.read_text())
    from_dict = run(table, ["scenario.periods=120", "controller.L_hat_ratio=0.5"])
    table["scenario"]["periods"] = 120
    table["controller"]["L_hat_ratio"] = 0.5
    edited = run(table)
    from_object = run(load(path), sets)
    assert len(from_file.traces) == 120
    for other in (from_dict, edited, from_object):
        assert other.traces.tobytes() == from_file.traces.tobytes()
        assert _summary(other.summary) == _summary(from_file.summary)
    assert from_file.traces.tobytes() != run(path, {"scenario.periods": 120}).traces.tobytes()  # the override acts


def test_bad_input_is_refused_naming_the_field_and_nothing_is_written(tmp_path: Path) -> None:
    path = REPO / SCENARIOS[0]
    with pytest.raises(ScenarioError, match=r"controller\.L_hat_ratio"):
        run(path, {"controller.L_hat_ratio": "half"}, out=tmp_path / "a")
    with pytest.raises(ScenarioError, match=r"no_such_key"):
        run(path, {"controller.no_such_key": 1}, out=tmp_path / "b")
    with pytest.raises(ScenarioError, match=r"override scenario\.periods"):
        run(path, {"scenario.periods": object()})
    with pytest.raises(TypeError, match="a TOML file's path, a dict or a Scenario"):
        run(42)  # type: ignore[arg-type]
    with pytest.raises(ScenarioError, match="cannot read"):
        run(tmp_path / "missing.toml")
    assert list(tmp_path.iterdir()) == []


def test_which_runs_go_in_process() -> None:
    assert in_process("direct") and not in_process("vcan0") and not in_process("can0")
    assert not in_process("direct", law=LAW)  # another build: a process of its own


def test_a_law_of_another_build_runs_in_its_own_process_and_reads_the_same(tmp_path: Path) -> None:
    scenario = REPO / "examples" / "scenarios" / "complex_vector_pi_step.toml"
    sets = {"scenario.periods": 450}
    r = run(scenario, sets, law=LAW)
    assert r.folder is None and not list(tmp_path.iterdir())  # a temporary folder, read and removed
    kept = run(scenario, sets, law=LAW, out=tmp_path / "kept")
    assert kept.folder == tmp_path / "kept"
    assert r.traces.tobytes() == np.load(kept.folder / "traces.npy").tobytes()
    assert _summary(r.summary) == _summary(kept.summary) and r.status == kept.status == "ok"
    assert r.summary["identified"]["controller"] == "complex_vector_pi"


def test_the_example_study_runs_as_a_user_runs_it(tmp_path: Path) -> None:
    """examples/library/inductance_study.py from another folder: a row per estimate, the matched one settling in two
    periods (You 2019), its plot written."""
    import subprocess
    import sys

    script = REPO / "examples" / "library" / "inductance_study.py"
    res = subprocess.run(
        [sys.executable, script, "--periods", "120", "--plot", "s.svg"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    rows = [line.split() for line in res.stdout.splitlines()[1:] if line.strip() and not line.startswith("plot:")]
    assert [r[0] for r in rows] == ["0.7", "0.8", "0.9", "1.0", "1.1", "1.2", "1.3"]
    matched = rows[3]
    assert matched[1] == "ok" and matched[2:4] == ["2", "per."], res.stdout
    assert (tmp_path / "s.svg").read_text().startswith("<?xml")
