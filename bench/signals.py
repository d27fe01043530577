"""Trace signals: their column names and SI units.

A column name is the EDS sub-entry name with its object's prefix (see `column_name`), and
it ends in its unit (`i_a_A`, `L_hat_H`, `K1_active_V_A`, `det_A2`): the unit is read off the
name, so the EDS is the only place it is written. Signals without a unit suffix are counts,
flags or dimensionless gains (unit "1").
"""

from __future__ import annotations

from dataclasses import dataclass

# Longest suffix first: "_V_A" before "_A", "_rad_s" before "_s".
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_K_per_W", "K/W"),
    ("_J_per_K", "J/K"),
    ("_per_K", "1/K"),
    ("_degC", "°C"),
    ("_ohm_Vs", "Ω/(V·s)"),
    ("_H_Vs", "H/(V·s)"),
    ("_rad_s2", "rad/s²"),
    ("_rad_s", "rad/s"),
    ("_V_A", "V/A"),
    ("_kgm2", "kg·m²"),
    ("_Nm", "N·m"),
    ("_ohm", "Ω"),
    ("_Wb", "Wb"),
    ("_A2", "A²"),
    ("_Hz", "Hz"),
    ("_rad", "rad"),
    ("_A", "A"),
    ("_V", "V"),
    ("_H", "H"),
    ("_J", "J"),
    ("_s", "s"),
)

# Objects whose entries keep their bare name in a trace (the loop's own quantities); entries of any
# other object are prefixed with the object's name, so two controllers' L_hat_H never collide.
BARE_OBJECTS = {
    "Measurement": "",
    "Voltage command": "",
    "Online tuning": "",
    "Plant state": "true_",
    "Drive status": "drive_",
    "Live trace": "live_",
}


def column_name(qualified: str) -> str:
    """'Object.sub' of the EDS -> the trace column ('Yao 2020 DPCC.L_hat_H' -> 'Yao_2020_DPCC_L_hat_H')."""
    obj, _, sub = qualified.partition(".")
    return BARE_OBJECTS.get(obj, obj.replace(" ", "_") + "_") + sub


def unit_of(name: str) -> str:
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return "1"


@dataclass(frozen=True)
class SignalInfo:
    name: str  # trace column, e.g. "Yao_2020_DPCC_R_hat_ohm"
    unit: str  # "Ω"
    source: str  # where it comes from: "plant TPDO1 Measurement.i_a_A", "derived", "scenario"
    storage: str = "<f8"  # dtype in traces.npy: "<f4" holds a REAL32 or a small integer exactly

    @classmethod
    def of(cls, name: str, source: str, storage: str = "<f8") -> SignalInfo:
        return cls(name, unit_of(name), source, storage)
