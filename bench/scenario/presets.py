"""The presets a scenario names: [motor] preset (PRESETS, the plant's motor presets) and [drive] preset
(DRIVE_PRESETS, expanded by drive_preset); and a motor preset's values (motor_preset) for the studies that derive
their expectations from the motor (bench/claims), loaded by the plant's own code from plant_rt/core/presets.c (each
value with its source there, the paper's table, and every assumption marked ASSUMED) through libhil.so, so a
study's numbers are the plant's doubles."""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from bench.paths import BUILD, MISSING_BUILD
from bench.scenario.model import ScenarioError

PRESETS = ("you2019", "yao2020_low", "yao2020_high", "zhao2022")
# [drive] presets. "ideal", the papers' simulated drive: no dead time (You 2019 Sec. 5, "the drive losses were ignored
# in the simulation": its 2 us of Table A1) and exact sensors (its 2500-line encoder of Sec. 6; no ADC noise or LSB:
# ASSUMED, as in Yao 2020 Sec. V and Zhao 2022 Sec. 5.1, whose Simulink models give none); the trip level stays on.
DRIVE_PRESETS = {"ideal": {"t_dead_s": 0.0, "encoder_lines": 0, "adc_noise_std_A": 0.0, "adc_lsb_A": 0.0}}


def drive_preset(where: str, values: dict[str, Any]) -> dict[str, Any]:
    """[drive] with its preset expanded (DRIVE_PRESETS): the preset's values first, the section's own after and over."""
    name = values.get("preset")
    if name is None:
        return values
    if not isinstance(name, str) or name not in DRIVE_PRESETS:
        raise ScenarioError(f"{where}: drive.preset = {name!r}: expected one of {', '.join(DRIVE_PRESETS)}")
    return {**DRIVE_PRESETS[name], **{k: v for k, v in values.items() if k != "preset"}}


@dataclass(frozen=True)
class MotorPreset:
    """A motor preset as plant_preset_load sets plant_config_t: the motor and inverter parameters every preset
    sets, and `values`, every field plant.eds carries (Motor model, Inverter, Sensors) after the load, by its
    EDS name."""

    name: str
    source: str  # the paper and its tables (presets.c k_presets)
    Ts_s: float
    Vdc_V: float
    pole_pairs: int
    R_ohm: float
    Ld_H: float
    Lq_H: float
    psi_Wb: float
    values: Mapping[str, float | int]


def _lib() -> ctypes.CDLL:
    path = BUILD / "libhil.so"
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing (the motor presets are read through it): {MISSING_BUILD}")
    lib = ctypes.CDLL(str(path))
    lib.hil_preset_count.restype = ctypes.c_uint32
    lib.hil_preset_name.restype = ctypes.c_char_p
    lib.hil_preset_name.argtypes = [ctypes.c_uint32]
    lib.hil_preset_source.restype = ctypes.c_char_p
    lib.hil_preset_source.argtypes = [ctypes.c_uint32]
    lib.hil_preset_field_count.restype = ctypes.c_uint32
    lib.hil_preset_field_name.restype = ctypes.c_char_p
    lib.hil_preset_field_name.argtypes = [ctypes.c_uint32]
    lib.hil_preset_values.restype = ctypes.c_int32
    lib.hil_preset_values.argtypes = [ctypes.c_char_p, ctypes.POINTER(ctypes.c_double), ctypes.c_uint32]
    return lib


def _text(raw: bytes | None) -> str:
    return (raw or b"").decode()


@functools.cache
def motor_presets() -> dict[str, MotorPreset]:
    """Every motor preset of plant_rt/core/presets.c, by name, in its table's order: loaded by the plant's own code
    (libhil.so's hil_preset_values: plant_preset_load, then plant_config_t's fields by their EDS names), so the
    values are the plant's doubles, not a copy."""
    lib = _lib()
    fields = [_text(lib.hil_preset_field_name(i)) for i in range(lib.hil_preset_field_count())]
    out = (ctypes.c_double * len(fields))()
    presets: dict[str, MotorPreset] = {}
    for i in range(lib.hil_preset_count()):
        name = _text(lib.hil_preset_name(i))
        if lib.hil_preset_values(name.encode(), out, len(fields)) != 0:
            raise ValueError(f"{name!r}: the plant lists it but does not load it")
        values: dict[str, float | int] = {f: out[k] for k, f in enumerate(fields)}
        values["pole_pairs"] = int(values["pole_pairs"])
        keys = ("Ts_s", "Vdc_V", "pole_pairs", "R_ohm", "Ld_H", "Lq_H", "psi_Wb")
        presets[name] = MotorPreset(
            name,
            _text(lib.hil_preset_source(i)),
            **{k: values[k] for k in keys},
            values=values,  # type: ignore[arg-type]
        )
    return presets


def motor_preset(name: str) -> MotorPreset:
    """The motor preset `name` ([motor] preset) as the plant loads it."""
    presets = motor_presets()
    if name not in presets:
        raise KeyError(f"{name!r}: no such motor preset in plant_rt/core/presets.c (it has {', '.join(presets)})")
    return presets[name]
