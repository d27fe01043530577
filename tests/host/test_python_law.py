"""A current law prototyped in Python in the direct loop (bench/law_py.py, bench/direct/hil_pylaw.c): called each
period in place of the registered law it names, with every check a C law gets (an exception or a NaN command is
law_fault, the run's frames kept to its end); the example law's Python twin equals its C port bit for bit; bad input
is refused before anything is written."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_cli import bench_cli

from bench.api import ScenarioError, run
from bench.paths import REPO

STEP = REPO / "scenarios" / "you2019_step.toml"
PI = {"scenario.periods": 120, "controller.controller": "pi"}
CVPI = REPO / "examples" / "laws" / "complex_vector_pi"
TWIN = f"{CVPI / 'prototype.py'}:ComplexVectorPI"


class Proportional:
    """A P law on both axes, standing in for the built-in PI (its record: Online tuning, pi_bandwidth_Hz)."""

    law = "pi"

    def __init__(self) -> None:
        self.steps = 0

    def configure(self, cfg: Any, record: Any, switched: bool) -> None:
        self.Kp = 2 * math.pi * record.pi_bandwidth_Hz * cfg.Lq_hat_H

    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        self.steps += 1
        vd, vq = self.Kp * (i.id_ref_A - i.i_d_A), self.Kp * (i.iq_ref_A - i.i_q_A)
        c, s = math.cos(i.theta_e_rad), math.sin(i.theta_e_rad)
        out.v_d_V, out.v_q_V, out.v_d_star_V, out.v_q_star_V = vd, vq, vd, vq
        out.v_alpha_V, out.v_beta_V = vd * c - vq * s, vd * s + vq * c


class Exploding(Proportional):
    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        if self.steps == 49:
            raise ZeroDivisionError("the prototype divided by zero")
        super().step(cfg, record, i, out)


class NotANumber(Proportional):
    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        super().step(cfg, record, i, out)
        if self.steps >= 30:
            out.v_alpha_V = math.nan


def test_a_python_law_runs_each_period_in_the_caller_s_process() -> None:
    law = Proportional()
    r = run(STEP, PI, py_law=law)
    assert law.steps == r.summary["python_law"]["steps"] == len(r.traces) == 120
    assert r.summary["python_law"]["law"] == "pi" and "exception" not in r.summary["python_law"]
    assert np.isfinite(r["v_alpha_V"]).all() and r["iq_A"][-1] > 0.5  # its P action moved the current


def test_a_law_that_raises_is_law_fault_and_the_run_keeps_its_frames() -> None:
    r = run(STEP, PI, py_law=Exploding())
    assert (r.status, r.exit_code) == ("law_fault", 10)
    exc = r.summary["python_law"]["exception"]
    assert (exc["method"], exc["at_step"]) == ("step", 50) and "ZeroDivisionError" in exc["error"]
    assert "the prototype divided by zero" in exc["traceback"] and "in step" in exc["traceback"]
    assert len(r.traces) == 120  # the frames to the run's end
    assert any("raised ZeroDivisionError" in n for n in r.summary["notes"])


def test_a_law_that_returns_nan_is_law_fault() -> None:
    r = run(STEP, PI, py_law=NotANumber())
    assert r.status == "law_fault" and "exception" not in r.summary["python_law"]
    assert 29 <= r.summary["status_first_period"]["law_fault"] <= 32


def test_the_example_law_s_twin_is_its_c_port_bit_for_bit(tmp_path: Path) -> None:
    """examples/laws/complex_vector_pi/prototype.py (numpy float32, the C library's cosf/sinf/expf/sqrtf) against
    complex_vector_pi.c, over the step scenario: every trace column, its status entries (traced) included."""
    scenario = REPO / "examples" / "scenarios" / "complex_vector_pi_step.toml"
    common = ("run", scenario, "--bus", "direct", "--law", CVPI, "--no-viewer")
    bench_cli(*common, "--out", tmp_path / "c", expect=0)
    bench_cli(*common, "--py-law", TWIN, "--out", tmp_path / "py", expect=0)
    c, py = np.load(tmp_path / "c" / "traces.npy"), np.load(tmp_path / "py" / "traces.npy")
    assert "Complex_vector_PI_x_d_V" in (c.dtype.names or ())  # the law's own status, traced
    assert c.dtype == py.dtype and c.tobytes() == py.tobytes()
    summary = json.loads((tmp_path / "py" / "summary.json").read_text())
    assert summary["python_law"]["steps"] == len(py) and summary["status"] == "ok"


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        (["--bus", "vcan0"], "--py-law runs in the direct loop only"),
        (["--bus", "direct", "--py-law", "nofile.py"], "expected FILE.py:Class"),
        (["--bus", "direct", "--py-law", "missing.py:Law"], "no such file"),
        (["--bus", "direct", "--py-law", "LAWFILE:Nope"], "has no Nope"),
        (["--bus", "direct", "--py-law", "LAWFILE:WrongName"], "name the registered law it stands in for"),
        (["--bus", "direct", "--py-law", "LAWFILE:Proportional"], "which the scenario never selects"),
    ],
)
def test_bad_input_is_refused_before_anything_is_written(tmp_path: Path, extra: list[str], said: str) -> None:
    law_file = tmp_path / "law.py"
    law_file.write_text(
        "class Proportional:\n    law = 'pi'\n    def configure(self, cfg, rec, sw): pass\n"
        "    def step(self, cfg, rec, i, out): pass\n"
        "class WrongName(Proportional):\n    law = 'no_such_law'\n"
    )
    args = [a.replace("LAWFILE", str(law_file)) for a in extra]
    if "--py-law" not in args:
        args += ["--py-law", f"{law_file}:Proportional"]
    res = bench_cli("run", STEP, *args, "--out", tmp_path / "out", "--no-viewer", expect=2)
    assert said in res.stderr, res.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


def test_the_library_refuses_a_law_the_scenario_never_runs() -> None:
    with pytest.raises(ScenarioError, match="never selects"):
        run(STEP, {"scenario.periods": 50}, py_law=Proportional())


CVPI_STEP = REPO / "examples" / "scenarios" / "complex_vector_pi_step.toml"


def test_port_check_finds_and_locates_a_one_ulp_change_in_the_port(tmp_path: Path) -> None:
    """`bench port-check`: the twin and its port agree bit for bit (exit 0); the port with its 2 pi constant one ULP
    higher parts from the twin (exit 1), and the report names the first period and the signals."""
    agree = bench_cli("port-check", CVPI_STEP, "--law", CVPI, "--py-law", TWIN, timeout=900, expect=0)
    assert "agree bit for bit" in agree.stdout
    events = tmp_path / "events.toml"  # the record and the drive's configuration changed mid-run: still one law
    events.write_text(
        CVPI_STEP.read_text().replace("periods = 700", "periods = 800")
        + "\n[[events]]\nat_period = 500\n"
        + "controller = { bandwidth_Hz = 600.0, cross_coupling = 0, discretisation = 0 }\n"
        + "\n[[events]]\nat_period = 600\ncontroller = { Vmax_V = 20.0, emf_feedforward = 0 }\n"
    )
    agree = bench_cli("port-check", events, "--law", CVPI, "--py-law", TWIN, timeout=900, expect=0)
    assert "over 800 periods" in agree.stdout and "agree bit for bit" in agree.stdout
    port = tmp_path / "complex_vector_pi"
    shutil.copytree(CVPI, port, ignore=shutil.ignore_patterns("prototype.py", "__pycache__"))
    c_file = port / "complex_vector_pi.c"
    text = c_file.read_text()
    one_ulp = float(np.nextafter(np.float32(6.28318530717959), np.float32(np.inf))).hex()
    changed = text.replace("#define CVPI_TWO_PI_F 6.28318530717959f", f"#define CVPI_TWO_PI_F {one_ulp}f")
    assert changed != text
    c_file.write_text(changed)
    report = tmp_path / "report.json"
    res = bench_cli("port-check", CVPI_STEP, "--law", port, "--py-law", TWIN, "--json", report, timeout=900, expect=1)
    data = json.loads(report.read_text())
    parted = [s for s in data["signals"] if s["first_beyond"] is not None]
    first = min(s["first_beyond"] for s in parted)
    assert not data["agree"] and {"vd_V", "vq_V", "v_alpha_V"} <= {s["name"] for s in parted}
    assert all(s["largest"] < 1e-3 for s in parted)  # one ULP in a gain: tiny, and found
    assert f"they part at period {first}, on " in res.stdout


def test_the_port_check_helper_in_process_and_in_a_law_build() -> None:
    from bench.api import port_check

    parted = port_check(STEP, Proportional(), PI)  # the PI's C port in this build, another law in Python
    assert not parted.agree and parted.first is not None and "they part at period" in parted.text()
    with pytest.raises(AssertionError, match="they part at period"):
        parted.expect_agree()
    port_check(CVPI_STEP, TWIN, law=CVPI).expect_agree()


class Cheat(Proportional):
    """Writes what C gives it as const: the drive's Vmax_V (what its command is checked against) and the command
    applied (what the drive sends after commit)."""

    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        cfg.Vmax_V = 1e6
        super().step(cfg, record, i, out)
        out.v_alpha_V = out.v_d_V = 500.0

    def commit(self, cfg: Any, record: Any, i: Any, applied: Any) -> None:
        applied.v_alpha_V = 500.0


def test_what_c_gives_as_const_cannot_be_changed_from_python() -> None:
    r = run(STEP, PI, py_law=Cheat())
    assert r.status == "law_fault"  # its 500 V was judged against the drive's own Vmax_V
    assert np.nanmax(np.abs(r["v_alpha_V"])) < 200.0  # the 500 V written into `applied` was never sent


class Interrupted(Proportional):
    def step(self, cfg: Any, record: Any, i: Any, out: Any) -> None:
        if self.steps == 49:
            raise KeyboardInterrupt
        super().step(cfg, record, i, out)


def test_a_ctrl_c_in_a_law_method_stops_the_loop_at_once() -> None:
    from bench.run.bus.direct import _lib

    with pytest.raises(KeyboardInterrupt):
        run(STEP, {**PI, "scenario.periods": 5000}, py_law=Interrupted())
    assert int(_lib().hil_plant_period()) < 100  # the plant's periods when the loop returned: not the run's 5000


def test_runs_from_two_threads_take_turns_and_give_the_same_numbers() -> None:
    from concurrent.futures import ThreadPoolExecutor

    alone = run(STEP, {"scenario.periods": 300}).traces.tobytes()
    with ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda _: run(STEP, {"scenario.periods": 300}), range(4)))
    assert all(r.status == "ok" and r.traces.tobytes() == alone for r in runs)
    with ThreadPoolExecutor(2) as pool:  # two Python laws: each run keeps its own
        laws = [Proportional() for _ in range(4)]
        done = list(pool.map(lambda law: run(STEP, PI, py_law=law), laws))
    assert all(law.steps == 120 for law in laws) and len({r.traces.tobytes() for r in done}) == 1


def test_the_library_refuses_what_a_law_process_could_not_load(tmp_path: Path) -> None:
    main_class = type("MyPI", (Proportional,), {"__module__": "__main__"})
    with pytest.raises(ScenarioError, match="defined in the script that runs"):
        run(CVPI_STEP, None, law=CVPI, py_law=main_class())
    with pytest.raises(ScenarioError, match=r"an instance of the law's class: Proportional\(\)"):
        run(STEP, PI, py_law=Proportional)
    from bench.api import port_check

    with pytest.raises(ScenarioError, match="tolerance = nan"):
        port_check(STEP, Proportional(), PI, tolerance=float("nan"))


def test_a_scenario_object_s_overrides_reach_a_law_process_and_a_law_file_imports_its_neighbours(
    tmp_path: Path,
) -> None:
    from bench.scenario import load

    sc = load(STEP, ["scenario.periods=150"])  # in this build; its run selects the law folder's law
    ran = run(sc, {"controller.controller": "complex_vector_pi"}, law=CVPI)  # a `bench run` process in the law's build
    assert len(ran.traces) == 150 and ran.summary["identified"]["controller"] == "complex_vector_pi"
    (tmp_path / "gains.py").write_text("def kp(bw, L):\n    return 6.283185307179586 * bw * L\n")
    (tmp_path / "my_law.py").write_text(
        "from gains import kp\n"
        "class P:\n    law = 'pi'\n"
        "    def configure(self, cfg, rec, sw):\n        self.k = kp(rec.pi_bandwidth_Hz, cfg.Lq_hat_H)\n"
        "    def step(self, cfg, rec, i, out):\n        out.v_alpha_V = self.k * (i.iq_ref_A - i.i_q_A)\n"
    )
    res = bench_cli(
        "run", STEP, "--bus", "direct", "--py-law", f"{tmp_path / 'my_law.py'}:P", "--set", "controller.controller=pi",
        "--set", "scenario.periods=60", "--out", tmp_path / "out", "--no-viewer", cwd=REPO,
    )  # fmt: skip
    assert res.returncode in (0, 7), res.stderr  # ran (its status is the law's business)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["python_law"]["steps"] == 60


def test_a_sweep_runs_every_point_with_the_python_law(tmp_path: Path) -> None:
    """`bench sweep --py-law`: a P law's steady-state error at standstill is R / (R + Kp) of the step, Kp = 2 pi
    f_bw Lq_hat (the You 2019 preset: R 1.4 ohm, Lq 4.54 mH), at each point of the bandwidth grid."""
    import pyarrow.parquet as pq

    law = tmp_path / "p_law.py"
    law.write_text(
        "import math\nclass P:\n    law = 'pi'\n"
        "    def configure(self, cfg, rec, sw):\n        self.k = 2 * math.pi * rec.pi_bandwidth_Hz * cfg.Lq_hat_H\n"
        "    def step(self, cfg, rec, i, out):\n"
        "        vd, vq = self.k * (i.id_ref_A - i.i_d_A), self.k * (i.iq_ref_A - i.i_q_A)\n"
        "        c, s = math.cos(i.theta_e_rad), math.sin(i.theta_e_rad)\n"
        "        out.v_alpha_V, out.v_beta_V = vd * c - vq * s, vd * s + vq * c\n"
    )
    bench_cli(
        "sweep", STEP, "--grid", "controller.pi_bandwidth_Hz=200,800", "--set", "controller.controller=pi",
        "--set", "scenario.periods=100", "--py-law", f"{law}:P", "--serial", "--out", tmp_path / "sw", expect=0,
    )  # fmt: skip
    rows = pq.read_table(tmp_path / "sw" / "sweep.parquet").to_pylist()
    for row in rows:
        kp = 2 * math.pi * float(row["controller.pi_bandwidth_Hz"]) * 4.54e-3
        assert abs(-row["steady_state_error_A"] - 1.4 / (1.4 + kp)) < 0.01, row
    assert len(rows) == 2
    refused = bench_cli("sweep", STEP, "--grid", "controller.L_hat_ratio=1,2", "--py-law", f"{law}:P", expect=2)
    assert "never selects" in refused.stderr
