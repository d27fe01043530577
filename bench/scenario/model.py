"""What a scenario is once parsed (Scenario, its Settings and Events) and the refusal of a bad one (ScenarioError),
with the fixed vocabularies of its [scenario] table: its keys, the timings, the run statuses it may expect."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from bench.eds import Param
from bench.scenario.faults import Fault

TIMINGS = ("lockstep", "realtime")
SCENARIO_KEYS = ("name", "description", "periods", "seed", "timing", "expect")
# Run statuses (bench/run/verdict/summary.py EXIT_CODES gives each its exit code).
STATUSES = (
    "ok",
    "tripped",
    "diverged",
    "non_finite",
    "frames_lost",
    "node_lost",
    "interference",
    "law_fault",
    "realtime_overrun",
    "plant_fault",
)


class ScenarioError(ValueError):
    """A bad scenario: the message names the file, the key and what is allowed."""


@dataclass(frozen=True)
class Setting:
    """One OD write, or a ratio resolved against the plant's value at configuration time."""

    key: str  # "section.name" as in the file
    param: Param | None  # None for ratio keys
    value: float | int
    ratio_of: tuple[tuple[str, str], ...] = ()  # ((drive param, plant param), ...)


@dataclass(frozen=True)
class FrameSet:
    """[frames] (bench/scenario/frames.py): the measurement's mapping and, for "compact", its coding (None: the
    bench chooses it from the plant's sensors at configuration: frames.coding_for)."""

    measurement: str = "default"  # or "compact" (8 bytes of integer codes), "single_frame" (16 bytes, CAN FD)
    current_lsb_A: float | None = None
    angle_counts: int | None = None
    period_mark: str = "sync"  # or "measurement": the one measurement frame marks the period, no SYNC frame
    can: str = "classic"  # or "fd": the PDOs in CAN FD frames (plant.eds / drive.eds 0x2105)
    bit_rate_switch: bool = True  # CAN FD frames with their data phase at the data bit rate

    @property
    def compact(self) -> bool:
        return self.measurement == "compact"

    @property
    def one_frame(self) -> bool:
        """The whole sample in one frame (compact or single_frame): it can mark the period."""
        return self.measurement in ("compact", "single_frame")

    @property
    def fd(self) -> bool:
        return self.can == "fd"

    @property
    def sync_less(self) -> bool:
        return self.period_mark == "measurement"


@dataclass
class Event:
    at_period: int
    settings: list[Setting]


@dataclass
class Scenario:
    name: str
    periods: int
    source: str
    description: str = ""
    seed: int = 1
    timing: str = "lockstep"
    preset: str | None = "you2019"
    settings: list[Setting] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    trace: dict[int, tuple[str, ...]] = field(default_factory=dict)  # TPDO number -> entries (parse)
    expect: tuple[str, ...] = ("ok",)
    faults: list[Fault] = field(default_factory=list)  # [[faults]] (bench/scenario/faults.py)
    raw: dict[str, Any] = field(default_factory=dict)
    motor_folder: Any = None  # bench.motor.MotorFolder of [motor] folder (its map is written to the plant's 0x2008)
    motor_fmu: Any = None  # bench.motor.fmu.FmuPlant of [motor.fmu] (its text is written to the plant's 0x2009)
    frames: FrameSet = field(default_factory=FrameSet)  # [frames] (bench/scenario/frames.py)
    trip_note: str | None = None  # a free rotor whose trip reaction may leave the flux map (bench/motor/trip.py)

    def event_periods(self) -> list[int]:
        return sorted({e.at_period for e in self.events})
