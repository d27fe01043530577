"""What the master reads by SDO at the end of every run (and so what every bus.log ends with), in a fixed order:
the nodes' statuses, the controller's settings, the selected law's results (drive.eds), the MCU's step cost, and
the plant values the verdict needs. The verdict (run/verdict/summary.py) reads them back from the log."""

from __future__ import annotations

from bench.eds import load
from bench.laws import result_reads

# What each law identifies or applies (read by SDO at the end of every run, and so in the log), and the
# drive's trace TPDOs of a run whose scenario has no [trace]: the keys Source / Results / Trace / ValidIf
# of the law's record in drive.eds, read by bench/laws.py (a user's law merged into drive.eds needs no
# edit here). PI and open loop identify nothing and trace the drive's own view (laws.DRIVE_VIEW).
CONTROLLER_VALUES = ("controller", "R_hat_ohm", "Ld_hat_H", "Lq_hat_H", "psi_hat_Wb", "Vmax_V", "Ts_s", "pole_pairs")
# Statuses read at the end: (node, object, entries).
END_READS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    (
        "plant",
        "Run control",
        ("missed_commands", "late_commands", "period_index", "trip_active", "outside_map_periods"),
    ),
    ("drive", "Drive status", ("current_steps", "lost_measurements", "late_measurements")),
    ("drive", "Controller", CONTROLLER_VALUES),
    *result_reads(),
)
# the drive's cost of one current step (0x2208, counted by the target's cycle counter around every step);
# read at the end of runs whose drive is the MCU image (bench run --drive mcu)
STEP_COST = (
    "drive",
    "Step cost",
    ("step_cycles_last", "step_cycles_max", "step_cycles_mean", "cycle_clock_Hz", "steps_measured"),
)
PLANT_VALUES = (
    ("Motor model", ("R_ohm", "Ld_H", "Lq_H", "psi_Wb", "pole_pairs", "J_kgm2", "mech_mode", "omega_imposed_rad_s")),
    ("Inverter", ("Ts_s", "Vdc_V", "I_trip_A", "trip_reaction")),
)


def _realtime_reads() -> tuple[str, str, tuple[str, ...]]:
    """The plant's real-time timing (0x2007), read at the end of a real-time run: every entry the plant
    reports (its read-only ones, from plant.eds); the plant computes the percentiles when they are read."""
    rec = load("plant")["Realtime timing"]
    return ("plant", rec.name, tuple(v.name for v in rec.values() if v.subindex > 0 and v.access_type == "ro"))


REALTIME_READS = _realtime_reads()
