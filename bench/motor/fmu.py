"""An FMU as the plant's machine (`[motor.fmu]` of a scenario, docs/YOUR_MOTOR.md): FMI 2.0 or 3.0 co-simulation
with a Linux x86-64 binary, read and checked with FMPy against its modelDescription.xml before anything starts (the
mapped variables' names, causality, variability, type and units where given), extracted once into the bench's
state folder, and described to the plant as the text of its object 0x2009 "FMU" (plant_rt/fmu/plant_fmu.h).

    [motor.fmu]
    file = "linear_pmsm.fmu"                                   # relative to the scenario's folder
    inputs = { v_alpha_V = "v_alpha", v_beta_V = "v_beta" }     # or { vd_V = ..., vq_V = ... }
    outputs = { i_a_A = "i_a", i_b_A = "i_b", theta_m_rad = "theta_m", omega_m_rad_s = "omega_m" }
                                                               # currents: i_a_A/i_b_A, i_alpha_A/i_beta_A or id_A/iq_A
    parameters = { R = 1.4 }                                   # optional: set before its initialization
    substeps = 1                                               # optional: doStep calls a period
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.extras import missing_extra
from bench.motor.folder import resolve
from bench.scenario.model import ScenarioError

INPUTS = {("v_alpha_V", "v_beta_V"): "alpha_beta", ("vd_V", "vq_V"): "dq"}
CURRENTS = {("i_a_A", "i_b_A"): "phase", ("i_alpha_A", "i_beta_A"): "alpha_beta", ("id_A", "iq_A"): "dq"}
UNITS = {"V": "V", "A": "A", "rad": "rad", "rad_s": "rad/s"}
KEYS = ("file", "inputs", "outputs", "parameters", "substeps")


@dataclass(frozen=True)
class FmuPlant:
    path: Path
    text: str  # the 0x2009 text
    model_name: str
    fmi: int


def _unit(name: str) -> str | None:
    for suffix, unit in (("_rad_s", "rad/s"), ("_rad", "rad"), ("_V", "V"), ("_A", "A")):
        if name.endswith(suffix):
            return unit
    return None


def _a(word: str) -> str:
    return ("an " if word[0] in "aeiou" else "a ") + word


def _variables(md: Any) -> dict[str, Any]:
    return {v.name: v for v in md.modelVariables}


def _check_var(where: str, md: Any, key: str, name: Any, causality: str, vars_: dict[str, Any]) -> Any:
    if not isinstance(name, str):
        raise ScenarioError(f"{where}: {key} = {name!r}: expected the FMU's variable name (a string)")
    if name not in vars_:
        have = sorted(v.name for v in md.modelVariables if v.causality == causality)
        listed = ", ".join(have) or "none"
        raise ScenarioError(f"{where}: {key} = {name!r}: the FMU has no variable {name!r} (its {causality}s: {listed})")
    v = vars_[name]
    if v.causality != causality:
        raise ScenarioError(
            f"{where}: {key} = {name!r}: {name!r} has causality {v.causality}, {key} needs {_a(causality)}"
        )
    if v.type not in ("Real", "Float64"):
        raise ScenarioError(f"{where}: {key} = {name!r}: {name!r} is a {v.type}, {key} needs a Real (Float64)")
    if causality != "parameter" and v.variability not in ("continuous", "discrete"):
        raise ScenarioError(f"{where}: {key} = {name!r}: {name!r} is {v.variability}, {key} needs it to vary")
    want = _unit(key.rsplit(".", 1)[-1])
    unit = v.unit or (v.declaredType.unit if getattr(v, "declaredType", None) is not None else None)
    if want and unit and unit != want:
        raise ScenarioError(f"{where}: {key} = {name!r}: {name!r} is in {unit!r}, {key} needs {want!r}")
    return v


def _pair(where: str, table: Any, what: str, choices: dict[tuple[str, str], str]) -> tuple[str, tuple[str, str]]:
    keys = set(table) if isinstance(table, dict) else set()
    for pair, frame in choices.items():
        if set(pair) <= keys:
            return frame, pair
    allowed = " or ".join(f"{{{', '.join(p)}}}" for p in choices)
    raise ScenarioError(f"{where}: motor.fmu.{what} must map {allowed} to the FMU's variables")


def load_fmu(where: str, table: Any, pole_pairs: int) -> FmuPlant:
    """The scenario's [motor.fmu], checked against the FMU's modelDescription.xml, extracted; ScenarioError with the
    key, the name and what is wrong otherwise."""
    if not isinstance(table, dict) or "file" not in table:
        raise ScenarioError(f'{where}: [motor.fmu] needs file = "x.fmu", inputs = {{...}} and outputs = {{...}}')
    for k in table:
        if k not in KEYS:
            raise ScenarioError(f"{where}: unknown key motor.fmu.{k}; allowed: {', '.join(KEYS)}")
    try:
        from fmpy import extract, read_model_description
    except ImportError:
        raise ScenarioError(f"{where}: {missing_extra('fmu', '[motor.fmu]', 'FMPy is not installed')}") from None
    path = resolve(where, table["file"], "motor.fmu.file", "a path to an .fmu").resolve()
    if not path.is_file():
        raise ScenarioError(f"{where}: motor.fmu.file = {table['file']!r}: {path} is missing")
    try:
        md = read_model_description(str(path), validate=True)
    except Exception as exc:  # noqa: BLE001 - FMPy's validation names the problem
        raise ScenarioError(f"{where}: {path}: not a valid FMU: {exc}") from None
    if not md.fmiVersion.startswith(("2", "3")):
        raise ScenarioError(f"{where}: {path}: FMI {md.fmiVersion}: the bench runs FMI 2.0 and 3.0 co-simulation FMUs")
    fmi = 2 if md.fmiVersion.startswith("2") else 3
    if md.coSimulation is None:
        raise ScenarioError(f"{where}: {path}: no co-simulation interface (the bench runs co-simulation FMUs)")
    ident = md.coSimulation.modelIdentifier
    platform = "linux64" if fmi == 2 else "x86_64-linux"
    import zipfile

    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    binary = f"binaries/{platform}/{ident}.so"
    if binary not in names:
        have = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
        raise ScenarioError(
            f"{where}: {path}: no binary for Linux x86-64 ({binary}); it has: {', '.join(have) or 'no binaries'}"
        )
    vars_ = _variables(md)
    lines = [f"fmi {fmi}", f"identifier {ident}"]
    in_frame, in_keys = _pair(where, table.get("inputs"), "inputs", INPUTS)
    lines.append(f"inputs {in_frame}")
    for n, k in enumerate(in_keys):
        v = _check_var(where, md, f"motor.fmu.inputs.{k}", table["inputs"][k], "input", vars_)
        lines.append(f"in{n} {v.valueReference}")
    outs = table.get("outputs")
    out_frame, out_keys = _pair(where, outs, "outputs", CURRENTS)
    lines.append(f"outputs {out_frame}")
    for n, k in enumerate(out_keys):
        v = _check_var(where, md, f"motor.fmu.outputs.{k}", outs[k], "output", vars_)
        lines.append(f"out{n} {v.valueReference}")
    if not isinstance(outs, dict) or "theta_m_rad" not in outs:
        raise ScenarioError(f"{where}: motor.fmu.outputs.theta_m_rad (the mechanical angle) is required")
    v = _check_var(where, md, "motor.fmu.outputs.theta_m_rad", outs["theta_m_rad"], "output", vars_)
    lines.append(f"theta {v.valueReference}")
    if "omega_m_rad_s" in outs:
        v = _check_var(where, md, "motor.fmu.outputs.omega_m_rad_s", outs["omega_m_rad_s"], "output", vars_)
        lines.append(f"omega {v.valueReference}")
    extra = set(outs) - {*out_keys, "theta_m_rad", "omega_m_rad_s"}
    if extra:
        raise ScenarioError(f"{where}: unknown output motor.fmu.outputs.{sorted(extra)[0]}")
    params = table.get("parameters", {})
    if not isinstance(params, dict):
        raise ScenarioError(f"{where}: motor.fmu.parameters must be a table of the FMU's parameters")
    for name, value in params.items():
        v = _check_var(where, md, f"motor.fmu.parameters.{name}", name, "parameter", vars_)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ScenarioError(f"{where}: motor.fmu.parameters.{name} = {value!r}: expected a finite number")
        lines.append(f"param {v.valueReference} {float(value)!r}")
    sub = table.get("substeps", 1)
    if isinstance(sub, bool) or not isinstance(sub, int) or not 1 <= sub <= 10000:
        raise ScenarioError(f"{where}: motor.fmu.substeps = {sub!r}: expected an integer in 1 .. 10000")
    lines += [f"pole_pairs {pole_pairs}", f"substeps {sub}"]
    folder = _extracted(path, extract)
    lines.append(f"library {folder / binary}")
    token = md.guid if fmi == 2 else md.instantiationToken
    lines.append(f"token {token}")
    res = folder / "resources"
    lines.append(f"resources {res.as_uri() + '/' if fmi == 2 else str(res) + '/'}")
    return FmuPlant(path, "\n".join(lines) + "\n", md.modelName, fmi)


def _extracted(path: Path, extract: Any) -> Path:
    """The FMU unzipped once per content into the bench's state folder (a run's plant loads its binary there)."""
    from bench.root import STATE

    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    folder = STATE / "fmu" / f"{path.stem}-{digest}"
    if not (folder / "modelDescription.xml").is_file():
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=folder.parent))  # this process's own
        extract(str(path), unzipdir=str(tmp))
        try:
            os.rename(tmp, folder)  # atomic; another process that got there first keeps its (same) copy
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
    (folder / "resources").mkdir(exist_ok=True)
    return folder
