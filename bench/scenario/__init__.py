"""Scenario files (TOML): what to run, checked against the EDS before anything starts.

Layout (every key optional except where noted)::

    [scenario]
    name = "you2019-step"        # required
    description = "..."
    periods = 400                # run length in control periods (required)
    seed = 1                     # ADC-noise seed
    timing = "lockstep"          # lockstep | realtime
    expect = "ok"                # the run status this scenario is meant to end with (or a list):
                                 # ok | tripped | diverged | non_finite | frames_lost |
                                 # node_lost | interference; a
                                 # stability-boundary study says expect = ["diverged", "tripped"]

    [motor]                      # plant.eds "Motor model", after the preset
    preset = "you2019"           # you2019 | yao2020_low | yao2020_high | zhao2022
    Lq_H = 4.54e-3

    [drive]                      # plant.eds "Inverter" and "Sensors", and the lockstep timeout
    preset = "ideal"             # DRIVE_PRESETS: its values first, the section's own keys after and over them
    Vdc_V = 300

    [controller]                 # drive.eds "Controller", "Outer loops", each current law's record (its
                                 # CurrentLaws key: "Online tuning", "Yao 2020 DPCC", ..., a user law's),
                                 # "Safe state" (meas_timeout_periods; clear = 1 in an event: fault reset + enable)
    controller = "deadbeat_you2019"
    L_hat_ratio = 0.5            # ratios to the plant's own values (R_hat_ratio, Ld_hat_ratio,
                                 # Lq_hat_ratio, L_hat_ratio = both, psi_hat_ratio)
    Vmax_V = 139

    [references]                 # drive.eds "References" at period 0
    iq_ref_A = 0.0

    [trace]                      # the drive's synchronous trace TPDOs (drive.eds names, REAL32/integers,
    pdo3 = ["Online tuning.det_A2", "Online tuning.K1_hat_V_A"]    # at most 8 bytes each); without it,
    pdo4 = ["Online tuning.K1_active_V_A", "Online tuning.L_hat_H"]  # the selected law's (default_trace)

    [[faults]]                   # faults on purpose (bench/scenario/faults.py): drop, delay, duplicate,
    kind = "drop"                # corrupt, reorder frames; silence_heartbeat, freeze, kill, reset nodes
    frame = "drive.TPDO1"
    at_period = 200

    [[events]]                   # applied before the current step of period `at_period`
    at_period = 100
    references = { iq_ref_A = 1.0 }
    controller = { enable = 1 }  # any key of the sections above (motor/drive changes hit the plant)

Every value is checked against the EDS: an unknown key names the allowed keys, a value
out of range names the range; nothing starts on a bad scenario.

This package's face: its modules, one concern each, and every name they offer, from here.

    model.py      Scenario, Setting, Event, ScenarioError; the [scenario] keys, timings and statuses
    presets.py    the [motor] and [drive] presets (a motor preset's values: plant_rt/core/presets.c)
    settings.py   a table's key = value checked against the EDS (SECTION_OBJECTS, RATIOS)
    parsing.py    parse: the tables, the events, the trace and the faults of a scenario
    overrides.py  --set KEY=VALUE and --law DIR
    files.py      load, loads, from_dict: a scenario from its file, its text or its tables
    faults.py     [[faults]]
    trace.py      [trace]
"""

from __future__ import annotations

from bench.scenario.faults import Fault, FaultError, parse_faults, refuse_lockstep_stalls
from bench.scenario.files import bundled, from_dict, load, loads, scenario_path
from bench.scenario.model import SCENARIO_KEYS, STATUSES, TIMINGS, Event, Scenario, ScenarioError, Setting
from bench.scenario.overrides import (
    add_set_argument,
    apply_overrides,
    set_items,
    unselected_law,
    unselected_python_law,
)
from bench.scenario.parsing import COMMAND_TIMEOUT, controller_at_start, default_trace, parse
from bench.scenario.presets import DRIVE_PRESETS, PRESETS, MotorPreset, motor_preset, motor_presets
from bench.scenario.settings import RATIOS, RESERVED, SECTION_OBJECTS
from bench.scenario.trace import TraceError, trace_table

__all__ = [
    "COMMAND_TIMEOUT",
    "DRIVE_PRESETS",
    "PRESETS",
    "RATIOS",
    "RESERVED",
    "SCENARIO_KEYS",
    "SECTION_OBJECTS",
    "STATUSES",
    "TIMINGS",
    "Event",
    "Fault",
    "FaultError",
    "MotorPreset",
    "Scenario",
    "ScenarioError",
    "Setting",
    "TraceError",
    "add_set_argument",
    "apply_overrides",
    "bundled",
    "controller_at_start",
    "default_trace",
    "load",
    "loads",
    "from_dict",
    "set_items",
    "motor_preset",
    "motor_presets",
    "parse",
    "parse_faults",
    "refuse_lockstep_stalls",
    "scenario_path",
    "trace_table",
    "unselected_law",
    "unselected_python_law",
]
