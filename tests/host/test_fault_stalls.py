"""Lockstep faults that would stall the loop (the plant waits for every command: [drive]
command_timeout_us = 0, its default) are refused before anything starts, naming the entry and the key."""

from __future__ import annotations

import pytest

from bench.scenario import ScenarioError, loads
from bench.scenario.faults import loop_frames

HEAD = """
[scenario]
name = "x"
periods = 100
{expect}
[motor]
preset = "you2019"
mech_mode = "locked"
[drive]
t_dead_s = 0.0
{timeout}
[[faults]]
{fault}
at_period = 21
"""

STALLS = [
    'kind = "drop"\nframe = "drive.TPDO1"',
    'kind = "drop"\nframe = "plant.TPDO2"',
    'kind = "drop"\nframe = "plant.TPDO2"\nprobability = 0.01',
    'kind = "delay"\nframe = "drive.TPDO1"\ndelay_periods = 1',
    'kind = "drop"\ncob_id = 0x210\nfrom = "drive"',
    'kind = "freeze"\nnode = "drive"\nperiods = 5',
    'kind = "corrupt"\nframe = "plant.TPDO2"\ndlc = 4',  # a short PDO is not processed: as dropped
]


def text(fault: str, timeout: str = "", expect: str = "") -> str:
    return HEAD.format(fault=fault, timeout=timeout, expect=expect)


@pytest.mark.parametrize("fault", STALLS)
def test_a_fault_that_stalls_lockstep_is_refused(fault: str) -> None:
    with pytest.raises(ScenarioError) as err:
        loads(text(fault), "s.toml")
    msg = str(err.value)
    assert msg.startswith("s.toml: faults[0]") and "command_timeout_us > 0" in msg and "[drive]" in msg, msg


@pytest.mark.parametrize("fault", STALLS)
def test_the_same_fault_runs_with_a_command_timeout_or_when_the_stall_is_expected(fault: str) -> None:
    assert loads(text(fault, timeout="command_timeout_us = 20000"), "s.toml").faults
    assert loads(text(fault, expect='expect = "frames_lost"'), "s.toml").faults


def test_a_timeout_set_by_an_event_before_the_fault_counts() -> None:
    src = text(STALLS[0]) + "\n[[events]]\nat_period = 10\ndrive = { command_timeout_us = 20000 }\n"
    assert loads(src, "s.toml").faults
    late = text(STALLS[0]) + "\n[[events]]\nat_period = 30\ndrive = { command_timeout_us = 20000 }\n"
    with pytest.raises(ScenarioError):
        loads(late, "s.toml")


def test_frames_outside_the_loop_and_harmless_kinds_are_not_refused() -> None:
    for fault in (
        'kind = "drop"\nframe = "drive.TPDO2"',
        'kind = "duplicate"\nframe = "drive.TPDO1"',
        'kind = "corrupt"\nframe = "drive.TPDO1"\nbit = 3',
        'kind = "drop"\nframe = "plant.heartbeat"',
        'kind = "drop"\nframe = "SYNC"',  # the drive steps on the sample all the same (the drop-sync check)
        'kind = "delay"\nframe = "SYNC"\ndelay_periods = 1',
        'kind = "drop"\nframe = "plant.TPDO1"',  # the drive steps on the held currents (late, reason 1)
    ):
        assert loads(text(fault), "s.toml").faults, fault


def test_the_loop_frames_come_from_the_eds() -> None:
    assert set(loop_frames().values()) == {"plant.TPDO2", "drive.TPDO1"}


def test_what_is_not_refused_does_not_stall() -> None:
    """The refusal's other side, run: a lockstep loop without a command timeout goes on through a dropped
    SYNC or current frame (so refusing them would turn away scenarios that run)."""
    from bench.run.options import RunOptions
    from bench.run.pipeline import run_scenario

    for fault in ('kind = "drop"\nframe = "SYNC"', 'kind = "drop"\nframe = "plant.TPDO1"'):
        res = run_scenario(loads(text(fault), "s.toml"), RunOptions(bus="direct"))
        assert res.summary["stopped"] is None and res.summary["periods"] == 100, (fault, res.summary["stopped"])
