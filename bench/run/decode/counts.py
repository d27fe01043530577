"""What the decoder counts while it decodes: per PDO and for the whole bus (the run's bus_stats and status)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bench.run.decode.layout import PdoLayout


@dataclass
class PdoStats:
    pdo: PdoLayout
    present: int = 0  # periods that got this PDO
    non_finite: int = 0  # periods whose frame carried a NaN or an infinity


@dataclass
class DecodeStats:
    periods: int = 0
    frames: int = 0
    # COB-ID -> frames on identifiers the run does not use (and foreign SYNCs)
    foreign: dict[int, int] = field(default_factory=dict)
    interference: dict[int, int] = field(default_factory=dict)  # COB-ID -> extra frames on the loop's own
    first_interference_period: int | None = None
    first_lost_period: int | None = None  # the first period with a missing frame, a gap or a misaligned sample
    after_loop_frames: int = 0
    teardown_frames: int = 0  # from the master's NMT Stop that ends the run on (decoder.py: never judged)
    sync_counter_gaps: int = 0
    sample_index_mismatches: int = 0
    pdos: dict[int, PdoStats] = field(default_factory=dict)
    non_finite: dict[str, int] = field(default_factory=dict)  # column -> periods with a non-finite value
    first_non_finite_period: int | None = None
    missing_measurements: int = 0  # periods without one of the plant's synchronous measurement PDOs
    missing_commands: int = 0  # periods without the drive's command PDO
    safe_state_commands: int = 0  # the drive's 0 V command sent at once on entering its safe state (drive_app.h)

    def lost(self, periods: np.ndarray) -> None:
        """Periods with a missing frame, a gap or a misaligned sample."""
        if len(periods):
            first = int(periods.min())
            if self.first_lost_period is None or first < self.first_lost_period:
                self.first_lost_period = first

    def interfere(self, cob_id: int, periods: np.ndarray) -> None:
        """Extra frames on one of the loop's own identifiers, one in each of these periods."""
        if len(periods) == 0:
            return
        self.interference[cob_id] = self.interference.get(cob_id, 0) + len(periods)
        first = int(periods.min())
        if self.first_interference_period is None or first < self.first_interference_period:
            self.first_interference_period = first
