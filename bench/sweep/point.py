"""One point of a study, run where a Dask worker (or the serial loop) runs it: the scenario with the
point's overrides, in direct mode and in memory (no file written or read), reduced to one row.

The row: the point's keys, the first iq step's metrics (bench/metrics.py), the run's status, the
controller's identified values, the growth per period of the iq error after the last reference change
(bench/metrics.py error_growth, as the Zhao 2022 stability claim measures it: < 1 exactly when the error
decays), and the time the point took next to its loop's own time.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

import numpy as np

from bench.metrics import error_growth, growth_windows

STEP_METRICS = ("periods_to_settle", "overshoot_pct", "overshoot_A", "steady_state_error_A")
# A point's row: the columns a condition (--until) may name, the numeric ones a plot may show
METRICS = (*STEP_METRICS, "error_growth_per_period", "max_phase_current_A", "status", "periods", "loop_s", "point_s")
NUMERIC = tuple(m for m in METRICS if m != "status")


class ErrorEnvelope:
    """A sink that keeps iq_ref - iq per period (float32, 4 bytes a period) for the growth metric, and the last
    sampled dq currents (the operating point a motor folder's truth is read at)."""

    def __init__(self) -> None:
        self._parts: list[np.ndarray] = []
        self.last_dq: tuple[float, float] | None = None

    def begin(self, signals: Any, ctx: Any) -> None:
        pass

    def write(self, chunk: dict[str, np.ndarray]) -> None:
        if "iq_A" in chunk and "iq_ref_A" in chunk:
            self._parts.append((chunk["iq_ref_A"] - chunk["iq_A"]).astype(np.float32))
        if "id_A" in chunk and "iq_A" in chunk and len(chunk["iq_A"]):
            self.last_dq = (float(chunk["id_A"][-1]), float(chunk["iq_A"][-1]))

    def end(self, summary: dict[str, Any]) -> None:
        pass

    def error(self) -> np.ndarray:
        return np.concatenate(self._parts) if self._parts else np.zeros(0, np.float32)


def growth_per_period(err: np.ndarray, last_change: int, step_A: float) -> float | None:
    """error_growth_per_period: the iq error's growth per period after the last reference change
    (bench/metrics.py error_growth over growth_windows); None when the window is too short or there is no step."""
    windows = growth_windows(len(err), last_change)
    if windows is None or not math.isfinite(step_A) or step_A == 0.0:
        return None
    return error_growth(err, step_A, *windows).per_period


def _number(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    return float(v)


def run_point(
    scenario_text: str, where: str, fixed: list[str], values: dict[str, str], py_law: str | None = None
) -> dict[str, Any]:
    """Run one point (`py_law`: its current law prototyped in Python, a new object a point); a point the scenario or
    a node refuses is a row with its reason, not the end of the study."""
    from bench.run import RunOptions, run_scenario
    from bench.scenario import ScenarioError, loads
    from bench.sweep.space import point_id

    row: dict[str, Any] = {"point_id": point_id(values), **values}
    t0 = time.perf_counter()
    try:
        sc = loads(scenario_text, where, [*fixed, *(f"{k}={v}" for k, v in values.items())])
        env = ErrorEnvelope()
        law = None
        if py_law is not None:
            from bench.law_py import load_law

            law = load_law(py_law)
        res = run_scenario(sc, RunOptions(bus="direct", py_law=law), sinks=[env], envelopes=False)  # no plot
    except (ScenarioError, ValueError, RuntimeError) as exc:
        row.update(status="refused", reason=str(exc), point_s=time.perf_counter() - t0, worker_pid=os.getpid())
        return row
    s = res.summary
    steps = [st for st in s["steps"] if st["signal"] == "iq"]
    first = steps[0] if steps else {}
    row.update({m: _number(first.get(m)) for m in STEP_METRICS})
    last = steps[-1] if steps else None
    row["error_growth_per_period"] = (
        growth_per_period(env.error(), int(last["at_period"]), float(last["to_A"]) - float(last["from_A"]))
        if last
        else None
    )
    row["max_phase_current_A"] = _number(s.get("max_phase_current_A"))
    row["status"] = s["status"]
    row["reason"] = (s.get("stopped") or {}).get("message")
    for k, v in s["identified"].items():
        if _number(v) is not None:
            row[f"identified.{k}"] = _number(v)
    row.update(motor_truth(sc, env.last_dq))
    row["periods"] = int(s["periods"])
    row["loop_s"] = float(s["timing"].get("run_wall_s") or 0.0)
    row["point_s"] = time.perf_counter() - t0
    row["worker_pid"] = os.getpid()
    return row


def motor_truth(sc: Any, dq: tuple[float, float] | None) -> dict[str, float]:
    """With a motor folder ([motor] folder): its map's incremental inductances at the point's last operating point
    (motor.Ldd_H, motor.Lqq_H, motor.Ldq_H) and the chord of psi_q from iq = 0 (motor.Lqq_chord_H): the truth an
    identified L_hat is compared with (docs/YOUR_MOTOR.md)."""
    if sc.motor_folder is None or sc.motor_folder.map is None or dq is None or not all(math.isfinite(v) for v in dq):
        return {}
    fm = sc.motor_folder.map
    e = fm.eval(dq[0], dq[1])
    out = {f"motor.{k}": float(e[k]) for k in ("Ldd_H", "Lqq_H", "Ldq_H")}
    if dq[1] != 0.0:
        out["motor.Lqq_chord_H"] = float((e["psi_q_Wb"] - fm.eval(dq[0], 0.0)["psi_q_Wb"]) / dq[1])
    return out


def run_batch(
    scenario_text: str, where: str, fixed: list[str], batch: list[dict[str, str]], py_law: str | None = None
) -> list[dict[str, Any]]:
    """Several points in one task: a Dask task costs about a millisecond of scheduling; a batch keeps
    that small next to short points."""
    return [run_point(scenario_text, where, fixed, values, py_law) for values in batch]
