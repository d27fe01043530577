"""A motor folder (docs/YOUR_MOTOR.md): `motor.toml` (the motor's name, source, pole pairs, R and its temperature
model, mechanics) and its machine model: a flux-map table (CSV or NumPy .npz), or the linear dq model's Ld_H, Lq_H,
psi_Wb with at most one machine model's own table (a plant.eds record "Model <name>": [harmonic]), read and checked
before anything starts. Every refusal (MotorError) names the file, the row or key, and the value; nothing is
half-loaded.

    [motor]
    name = "..."               # required
    source = "..."             # required: where the data comes from (FEA run, measurement, a model and its paper)
    pole_pairs = 4             # required
    R_ohm = 0.2                # required: phase resistance at T_ref_degC
    J_kgm2 = 1e-3              # optional (the preset's otherwise); B_Nm_per_rad_s too
    I_trip_A = 12              # optional: the over-current trip level, per phase (default: sqrt(3)/2 of where the map
                               # ends: the dq currents stay inside it)
    [flux_map]
    file = "flux_map.csv"      # required: CSV (id_A,iq_A,psi_d_Wb,psi_q_Wb, a row per grid point) or .npz
    [thermal]                  # optional: R follows the winding's temperature (plant.eds Motor model)
    R_alpha_per_K = 0.00393
    T_ref_degC = 20
    T_amb_degC = 40
    thermal_R_K_per_W = 0.5
    thermal_C_J_per_K = 400

Without [flux_map] the folder's [motor] also gives Ld_H, Lq_H and psi_Wb (required), and the machine model is
dq_linear, or the one whose table follows ([harmonic]: psi_5_Wb, psi_7_Wb, cogging_Nm, cogging_periods, the keys of
plant.eds "Model harmonic"; any model's record gives its table, bench.eds.model_records).
"""

from __future__ import annotations

import csv
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from canopen.objectdictionary import datatypes

from bench.motor.fluxmap import MAX_POINTS, FluxMap
from bench.scenario.model import ScenarioError

DESCRIPTION = "motor.toml"
INTEGER_TYPES = datatypes.INTEGER_TYPES  # an entry a motor.toml gives as an integer
COLUMNS = ("id_A", "iq_A", "psi_d_Wb", "psi_q_Wb")
MOTOR_KEYS = {
    "name": str,
    "source": str,
    "pole_pairs": int,
    "R_ohm": float,
    "J_kgm2": float,
    "B_Nm_per_rad_s": float,
    "I_trip_A": float,
}
REQUIRED = ("name", "source", "pole_pairs", "R_ohm")
LINEAR_KEYS = ("Ld_H", "Lq_H", "psi_Wb")  # [motor] keys of a folder without a map (the map's small-signal otherwise)
THERMAL_KEYS = ("R_alpha_per_K", "T_ref_degC", "T_amb_degC", "thermal_R_K_per_W", "thermal_C_J_per_K")


class MotorError(ValueError):
    """A motor folder the bench refuses: the message names the file, the row or key, and the value."""


@dataclass(frozen=True)
class MotorFolder:
    path: Path
    name: str
    source: str
    map: FluxMap | None  # the flux map (model flux_map), None for a model without one
    map_file: Path | None
    values: dict[str, float | int] = field(default_factory=dict)  # plant.eds Motor model entries, by name
    rows: dict[tuple[int, int], int] = field(default_factory=dict)  # grid point -> CSV row (for messages)
    model: str = "flux_map"  # plant.eds Motor model.model's ValueName

    def where(self, i: int | None, j: int | None, other: tuple[int, int] | None = None) -> str:
        """A grid point (and the one it is compared with) as the user finds it: the CSV rows, or the arrays' indices
        of an .npz."""
        if i is None or j is None or self.map is None:
            return str(self.map_file)
        if (i, j) in self.rows:
            then = f" and row {self.rows[other]}" if other in self.rows else ""
            return f"{self.map_file}: row {self.rows[(i, j)]}{then}"
        return f"{self.map_file}: [{i}, {j}] (id_A = {self.map.id_A[i]:g}, iq_A = {self.map.iq_A[j]:g})"


def load(folder: str | Path) -> MotorFolder:
    """The motor folder at `folder`, read and checked (MotorError otherwise)."""
    path = Path(folder).resolve()
    desc = path / DESCRIPTION
    if not path.is_dir():
        raise MotorError(f"{path}: not a folder (a motor folder holds {DESCRIPTION} and its flux-map table)")
    if not desc.is_file():
        raise MotorError(f"{desc}: missing (a motor folder's description: docs/YOUR_MOTOR.md)")
    try:
        raw = tomllib.loads(desc.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise MotorError(f"{desc}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise MotorError(f"{desc}: cannot read: {exc}") from None
    models = model_tables()
    allowed = ("motor", "flux_map", "thermal", *models)
    for table in raw:
        if table not in allowed:
            raise MotorError(f"{desc}: unknown table [{table}]; allowed: {', '.join(f'[{t}]' for t in allowed)}")
    chosen = [t for t in raw if t in ("flux_map", *models)]
    if len(chosen) > 1:
        raise MotorError(f"{desc}: [{chosen[0]}] and [{chosen[1]}]: a folder describes one machine model")
    values = _motor_values(desc, raw.get("motor"), linear="flux_map" not in raw)
    thermal = _thermal_values(desc, raw.get("thermal"))
    _in_range(desc, "motor", values)
    _in_range(desc, "thermal", thermal)
    values.update(thermal)
    if "flux_map" not in raw:
        return _model_folder(path, desc, raw, values, models)
    fm = raw.get("flux_map")
    if not isinstance(fm, dict) or not isinstance(fm.get("file"), str):
        raise MotorError(f'{desc}: [flux_map] file = "..." is required (a .csv or .npz in the folder)')
    if set(fm) - {"file"}:
        raise MotorError(f"{desc}: unknown key flux_map.{sorted(set(fm) - {'file'})[0]}; allowed: file")
    map_file = path / fm["file"]
    if not map_file.is_file():
        raise MotorError(f"{desc}: flux_map.file = {fm['file']!r}: {map_file} is missing")
    if map_file.suffix == ".csv":
        fmap, rows = _read_csv(map_file)
    elif map_file.suffix == ".npz":
        fmap, rows = _read_npz(map_file), {}
    else:
        raise MotorError(f"{desc}: flux_map.file = {fm['file']!r}: expected a .csv or .npz table")
    motor = MotorFolder(path, str(values.pop("name")), str(values.pop("source")), fmap, map_file, values, rows)
    problems = fmap.problems()
    if problems:
        lines = [f"{motor.where(p.i, p.j, p.other)}: {p.what}" for p in problems]
        raise MotorError("the flux map is refused:\n  " + "\n  ".join(lines))
    return motor


def model_tables() -> dict[str, str]:
    """A motor folder's table of each machine model with a record of its own (plant.eds "Model <name>"): the table
    [<name>] -> the record."""
    from bench.eds import MODEL_RECORD, model_records

    return {rec[len(MODEL_RECORD) :]: rec for rec in model_records()}


def _model_folder(
    path: Path, desc: Path, raw: dict[str, Any], values: dict[str, Any], models: dict[str, str]
) -> MotorFolder:
    """A folder without a map: the linear dq model, or the model whose table it has (its keys those of the model's
    record, numbers; their ranges are the EDS's, checked with the scenario's own)."""
    from bench.eds import params

    chosen = [t for t in raw if t in models]  # at most one (load)
    if "thermal" in raw:
        raise MotorError(f"{desc}: [thermal] is the flux-map model's (the plant's other models keep R constant)")
    model = chosen[0] if chosen else "dq_linear"
    if chosen:
        table, keys = raw[model], params("plant", (models[model],))
        if not isinstance(table, dict):
            raise MotorError(f"{desc}: [{model}] must be a table")
        for key, value in table.items():
            if key not in keys:
                raise MotorError(f"{desc}: unknown key {model}.{key}; allowed: {', '.join(keys)}")
            if not _number(value, integer=keys[key].data_type in INTEGER_TYPES):
                raise MotorError(f"{desc}: {model}.{key} = {value!r}: expected {_kind(_type(keys[key]))}")
            values[key] = value
        _in_range(desc, model, {k: v for k, v in values.items() if k in keys}, keys)
    name, source = str(values.pop("name")), str(values.pop("source"))
    return MotorFolder(path, name, source, None, None, values, model=model)


def _motor_values(desc: Path, motor: Any, linear: bool) -> dict[str, Any]:
    """[motor]'s values; `linear`: the folder has no map, so Ld_H, Lq_H and psi_Wb are its."""
    if not isinstance(motor, dict):
        raise MotorError(f"{desc}: missing [motor] table with at least {', '.join(REQUIRED)}")
    known = {**MOTOR_KEYS, **dict.fromkeys(LINEAR_KEYS, float)} if linear else MOTOR_KEYS
    out: dict[str, Any] = {}
    for key, value in motor.items():
        if key in LINEAR_KEYS and not linear:
            raise MotorError(
                f"{desc}: motor.{key}: a folder with a [flux_map] takes its {', '.join(LINEAR_KEYS)} from the map "
                "(its slope at zero current); remove the key"
            )
        if key not in known:
            raise MotorError(f"{desc}: unknown key motor.{key}; allowed: {', '.join(known)}")
        kind = known[key]
        ok = isinstance(value, str) if kind is str else _number(value, integer=kind is int)
        if not ok or (kind is str and not value.strip()):
            raise MotorError(f"{desc}: motor.{key} = {value!r}: expected {_kind(kind)}")
        out[key] = value
    for key in (*REQUIRED, *LINEAR_KEYS) if linear else REQUIRED:
        if key not in out:
            why = " (a folder without a [flux_map] gives the linear dq model's Ld_H, Lq_H, psi_Wb)" if linear else ""
            raise MotorError(f"{desc}: motor.{key} is required{why}")
    if not out["R_ohm"] > 0:
        raise MotorError(f"{desc}: motor.R_ohm = {out['R_ohm']!r}: a phase resistance must be > 0")
    return out


def _in_range(desc: Path, table: str, values: dict[str, Any], keys: dict[str, Any] | None = None) -> None:
    """Each EDS entry of the folder's `table` in its plant.eds range (the scenario's own check, bench.scenario.settings
    setting), named as the file writes it ("harmonic.psi_5_Wb"): refused here, before anything starts."""
    from bench.scenario.settings import param_tables, setting

    tables = param_tables()
    own = keys if keys is not None else {**tables["motor"], "I_trip_A": tables["drive"]["I_trip_A"]}
    for key, value in values.items():
        if key in own:
            try:
                setting(str(desc), table, key, value, {table: own})
            except ScenarioError as exc:
                raise MotorError(str(exc)) from None


def _thermal_values(desc: Path, thermal: Any) -> dict[str, float]:
    if thermal is None:
        return {}
    if not isinstance(thermal, dict):
        raise MotorError(f"{desc}: [thermal] must be a table")
    out: dict[str, float] = {}
    for key, value in thermal.items():
        if key not in THERMAL_KEYS:
            raise MotorError(f"{desc}: unknown key thermal.{key}; allowed: {', '.join(THERMAL_KEYS)}")
        if not _number(value, integer=False):
            raise MotorError(f"{desc}: thermal.{key} = {value!r}: expected a number")
        out[key] = float(value)
    return out


def _number(v: Any, integer: bool) -> bool:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return False
    return float(v) == int(v) if integer else True


def _type(p: Any) -> type:
    return int if p.data_type in INTEGER_TYPES else float


def _kind(kind: type) -> str:
    return {str: "a non-empty string", int: "an integer", float: "a finite number"}[kind]


def _read_csv(path: Path) -> tuple[FluxMap, dict[tuple[int, int], int]]:
    """A row per grid point (any order; '#' lines are comments): the grid is the sorted distinct id_A and iq_A."""
    points: dict[tuple[float, float], tuple[float, float, int]] = {}
    try:
        with path.open(newline="") as f:
            lines = [(n, ln) for n, ln in enumerate(f, start=1) if ln.strip() and not ln.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise MotorError(f"{path}: cannot read (a CSV of UTF-8 text): {exc}") from None
    if not lines:
        raise MotorError(f"{path}: empty (expected a header {','.join(COLUMNS)} and a row per grid point)")
    header_row, header = lines[0]
    cols = [c.strip() for c in next(csv.reader([header]))]
    if cols != list(COLUMNS):
        raise MotorError(f"{path}: row {header_row}: header {','.join(cols)!r}: expected {','.join(COLUMNS)}")
    for n, line in lines[1:]:
        cells = [c.strip() for c in next(csv.reader([line]))]
        if len(cells) != len(COLUMNS):
            raise MotorError(f"{path}: row {n}: {len(cells)} values, expected {len(COLUMNS)} ({','.join(COLUMNS)})")
        vals = []
        for col, cell in zip(COLUMNS, cells, strict=True):
            try:
                v = float(cell)
            except ValueError:
                raise MotorError(f"{path}: row {n}: {col} = {cell!r} is not a number") from None
            if not math.isfinite(v):
                raise MotorError(f"{path}: row {n}: {col} = {cell!r} is not finite")
            vals.append(v)
        key = (vals[0], vals[1])
        if key in points:
            raise MotorError(
                f"{path}: row {n}: the point id_A = {key[0]:g}, iq_A = {key[1]:g} is already row {points[key][2]}"
            )
        points[key] = (vals[2], vals[3], n)
    ids = np.array(sorted({k[0] for k in points}))
    iqs = np.array(sorted({k[1] for k in points}))
    if len(ids) > MAX_POINTS or len(iqs) > MAX_POINTS or len(ids) < 2 or len(iqs) < 2:
        raise MotorError(
            f"{path}: {len(ids)} values of id_A and {len(iqs)} of iq_A: a map needs 2 .. {MAX_POINTS} per axis"
        )
    pd = np.empty((len(ids), len(iqs)))
    pq = np.empty_like(pd)
    rows: dict[tuple[int, int], int] = {}
    for i, a in enumerate(ids):
        for j, b in enumerate(iqs):
            if (a, b) not in points:
                raise MotorError(
                    f"{path}: the grid is not complete: no row for id_A = {a:g}, iq_A = {b:g} "
                    f"({len(points)} rows for a {len(ids)} x {len(iqs)} grid)"
                )
            pd[i, j], pq[i, j], rows[(i, j)] = points[(a, b)]
    return FluxMap(ids, iqs, pd, pq), rows


def _read_npz(path: Path) -> FluxMap:
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise MotorError(f"{path}: not a NumPy .npz file: {exc}") from None
    missing = [c for c in COLUMNS if c not in z.files]
    if missing:
        raise MotorError(
            f"{path}: missing array {missing[0]} (expected {', '.join(COLUMNS)}; has {', '.join(z.files)})"
        )
    ids, iqs = np.asarray(z["id_A"], float), np.asarray(z["iq_A"], float)
    if ids.ndim != 1 or iqs.ndim != 1:
        raise MotorError(f"{path}: id_A and iq_A must be 1-D grids (shapes {ids.shape}, {iqs.shape})")
    for name in ("id_A", "iq_A"):
        g = ids if name == "id_A" else iqs
        bad = np.flatnonzero(~np.isfinite(g))
        if len(bad):
            raise MotorError(f"{path}: {name}[{bad[0]}] = {g[bad[0]]} is not finite")
    return FluxMap(ids, iqs, np.asarray(z["psi_d_Wb"], float), np.asarray(z["psi_q_Wb"], float))


def resolve(where: str, folder: Any, key: str = "motor.folder", what: str = "a folder path") -> Path:
    """The path a scenario names: relative to the scenario file's folder (to the working folder for a text)."""
    if not isinstance(folder, str) or not folder:
        raise ScenarioError(f"{where}: {key} = {folder!r}: expected {what} (a string)")
    p = Path(folder).expanduser()
    if p.is_absolute():
        return p
    base = Path(where).parent if Path(where).is_file() else Path.cwd()
    return base / p
