"""What a motor folder gives a scenario ([motor] folder = "DIR", `bench run --motor DIR`): the plant settings of
plant.eds "Motor model" (the folder's values, model = flux_map, and the map's small-signal Ld_H, Lq_H, psi_Wb, which
the drive's controller is configured from; a folder without a map: its model and its values as they are; the
over-current trip level, the folder's I_trip_A or where the map ends), and the check of the map's range against the
inverter's trip level (the plant must not extrapolate the map before it trips) and, given the scenario, against what
the trip does (bench/motor/trip.py: the short-circuit current at the run's speed)."""

from __future__ import annotations

import math
from typing import Any

from bench.eds import Param
from bench.motor.folder import MotorError, MotorFolder, load, resolve
from bench.motor.trip import TripNote
from bench.scenario.model import ScenarioError, Setting
from bench.scenario.settings import setting

# The trip is per phase (plant_inverter.c): a phase current of at most I_trip allows a dq current (amplitude-invariant)
# of up to 2/sqrt(3) I_trip along an axis between two phases; the map must hold that.
DQ_PER_PHASE = math.sqrt(3.0) / 2.0


def folder_settings(where: str, folder: Any, tables: dict[str, dict[str, Param]]) -> tuple[MotorFolder, list[Setting]]:
    """The motor folder and its plant settings, each checked against the EDS as a scenario's own."""
    path = resolve(where, folder)
    try:
        motor = load(path)
    except MotorError as exc:
        raise ScenarioError(f"{where}: motor.folder = {folder!r}: {exc}") from None
    if motor.map is None:  # the linear dq model or a model of its own table: the folder gives every value
        values: dict[str, Any] = {"model": motor.model, **motor.values}
        trip = values.pop("I_trip_A", None)
        return motor, _settings(where, folder, motor, values, trip, tables)
    Ld, Lq, psi = motor.map.small_signal()
    # the model first: the plant accepts the thermal entries on the flux-map model only
    values = {"model": "flux_map", "Ld_H": Ld, "Lq_H": Lq, "psi_Wb": psi, **motor.values}
    trip = values.pop("I_trip_A", None)
    if trip is None:  # the plant trips before the dq currents can leave the map
        edge = min(-float(motor.map.id_A[0]), float(motor.map.id_A[-1]), -float(motor.map.iq_A[0]),
                   float(motor.map.iq_A[-1]))  # fmt: skip
        if edge <= 0.0:
            raise ScenarioError(
                f"{where}: motor.folder = {folder!r}: the flux map {motor.map_file} covers id_A "
                f"{motor.map.id_A[0]:g} .. {motor.map.id_A[-1]:g} A and iq_A {motor.map.iq_A[0]:g} .. "
                f"{motor.map.iq_A[-1]:g} A: a run's currents take both signs (a step's overshoot, the trip's "
                "transient); extend the map to negative and positive currents on both axes (docs/YOUR_MOTOR.md)"
            )
        trip = edge * DQ_PER_PHASE
    return motor, _settings(where, folder, motor, values, trip, tables)


def _settings(
    where: str, folder: Any, motor: MotorFolder, values: dict[str, Any], trip: Any, tables: dict[str, dict[str, Param]]
) -> list[Setting]:
    """The folder's values (and its trip level, when it has one) as plant settings, each checked against the EDS."""
    out = []
    desc = str(motor.path / "motor.toml")
    try:
        for key, value in values.items():
            out.append(setting(desc, "motor", key, value, tables))
        if trip is not None:
            out.append(setting(desc, "drive", "I_trip_A", trip, tables))
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: motor.folder = {folder!r}: {exc}") from None
    return out


def check_range(where: str, motor: MotorFolder, trip_A: float, scenario: Any = None) -> TripNote | None:
    """The map must cover the currents the plant can reach before its over-current trip: [-I_trip, I_trip] on
    both axes, times 2/sqrt(3) (the trip is per phase); a trip level of 0, off, asks for nothing. The folder's
    trip level (motor.I_trip_A, else where the map ends, times sqrt(3)/2) is the default; a scenario's
    drive.I_trip_A beyond the map is refused.  With the scenario (parsed, its events too), the currents after the
    trip as well: its drive.trip_reaction at its speed (bench/motor/trip.py check_trip: a refusal, or for a free
    rotor the note the run's summary should carry)."""
    fm = motor.map
    if trip_A <= 0 or fm is None:  # no trip, or no map to leave
        return None
    reach = trip_A / DQ_PER_PHASE
    for axis, g in (("id_A", fm.id_A), ("iq_A", fm.iq_A)):
        if g[0] > -reach * (1 - 1e-9) or g[-1] < reach * (1 - 1e-9):  # (rounding of the default)
            raise ScenarioError(
                f"{where}: the flux map {motor.map_file} covers {axis} {g[0]:g} .. {g[-1]:g} A, but with the "
                f"inverter's trip at {trip_A:g} A a phase (drive.I_trip_A) the dq currents reach +-{reach:.4g} A: "
                f"the plant would extrapolate the map; extend the map to +-{reach:.4g} A or set drive.I_trip_A "
                f"<= {min(-g[0], g[-1]) * DQ_PER_PHASE:.4g} A"
            )
    if scenario is None:
        return None
    from bench.motor.trip import check_trip

    return check_trip(where, motor, scenario, trip_A)


def fmu_settings(
    where: str, table: Any, preset: str | None, motor: dict[str, Any], tables: dict[str, dict[str, Param]]
) -> tuple[Any, list[Setting]]:
    """[motor.fmu]: the FMU checked and extracted (bench/motor/fmu.py) and the plant's model = fmu. The pole pairs
    (for dq inputs or outputs) are the scenario's motor.pole_pairs, else its preset's."""
    from bench.motor.fmu import load_fmu

    pp = motor.get("pole_pairs")
    if pp is None:
        from bench.scenario.presets import motor_preset

        pp = motor_preset(preset or "you2019").pole_pairs
    fmu = load_fmu(where, table, int(pp))
    return fmu, [setting(where, "motor", "model", "fmu", tables)]
