"""What a motor folder gives a scenario ([motor] folder = "DIR", `bench run --motor DIR`): the plant settings of
plant.eds "Motor model" (the folder's values, model = flux_map, and the map's small-signal Ld_H, Lq_H, psi_Wb, which
the drive's controller is configured from; the over-current trip level, the folder's I_trip_A or where the map
ends), and the check of the map's range against the inverter's trip level
(the plant must not extrapolate the map before it trips)."""

from __future__ import annotations

from typing import Any

from bench.eds import Param
from bench.motor.folder import MotorError, MotorFolder, load, resolve
from bench.scenario.model import ScenarioError, Setting
from bench.scenario.settings import setting


def folder_settings(where: str, folder: Any, tables: dict[str, dict[str, Param]]) -> tuple[MotorFolder, list[Setting]]:
    """The motor folder and its plant settings, each checked against the EDS as a scenario's own."""
    path = resolve(where, folder)
    try:
        motor = load(path)
    except MotorError as exc:
        raise ScenarioError(f"{where}: motor.folder = {folder!r}: {exc}") from None
    Ld, Lq, psi = motor.map.small_signal()
    # the model first: the plant accepts the thermal entries on the flux-map model only
    values: dict[str, Any] = {"model": "flux_map", "Ld_H": Ld, "Lq_H": Lq, "psi_Wb": psi, **motor.values}
    trip = values.pop("I_trip_A", None)
    if trip is None:  # the plant trips where the map ends, not past it
        trip = min(-float(motor.map.id_A[0]), float(motor.map.id_A[-1]), -float(motor.map.iq_A[0]),
                   float(motor.map.iq_A[-1]))  # fmt: skip
        trip = max(trip, 0.0)
    out = []
    desc = str(motor.path / "motor.toml")
    try:
        for key, value in values.items():
            out.append(setting(desc, "motor", key, value, tables))
        out.append(setting(desc, "drive", "I_trip_A", trip, tables))
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: motor.folder = {folder!r}: {exc}") from None
    return motor, out


def check_range(where: str, motor: MotorFolder, trip_A: float) -> None:
    """The map must cover the currents the plant can reach before its over-current trip: [-I_trip, I_trip] on
    both axes (a trip level of 0, off, asks for nothing). The folder's trip level (motor.I_trip_A, else the map's
    range) is the default; a scenario's drive.I_trip_A beyond the map is refused."""
    if trip_A <= 0:
        return
    fm = motor.map
    for axis, g in (("id_A", fm.id_A), ("iq_A", fm.iq_A)):
        if g[0] > -trip_A or g[-1] < trip_A:
            raise ScenarioError(
                f"{where}: the flux map {motor.map_file} covers {axis} {g[0]:g} .. {g[-1]:g} A, but the inverter trips "
                f"only at {trip_A:g} A (drive.I_trip_A): the plant would extrapolate the map; extend the map to "
                f"+-{trip_A:g} A or set a lower drive.I_trip_A"
            )


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
