"""A drive team's current-loop spec, as their CI runs it on every pull request (docs/CI.md).

`pip install pmsm-hil-bench` enables the pytest plugin: the `hil_run` fixture runs a scenario on the bus
chosen by --hil-bus (direct by default: both nodes in process, bit-identical to vcan), and the result's
expect_* helpers fail with the measured figure, the bound and the run folder. The bounds below are the
team's spec; the bench measures (`bench run scenarios/iq_step.toml --bus direct`): 4 periods, 0.6 %,
0.8 mA when matched; 6 periods, 5.5 % with L_hat 30 % high; a command dropped after the step: 11 periods.
"""

from pathlib import Path

SCENARIO = Path(__file__).parent / "scenarios" / "iq_step.toml"


def test_step_meets_the_spec(hil_run):
    run = hil_run(SCENARIO)
    run.expect_status("ok")
    run.expect_settles_within(5)  # periods, every step of the run
    run.expect_overshoot_below(1.0)  # percent of the step
    run.expect_steady_state_error_below(0.002)  # A


def test_inductance_30_percent_high_stays_within_spec(hil_run):
    run = hil_run(SCENARIO, {"controller.L_hat_ratio": 1.3})
    run.expect_status("ok")
    run.expect_settles_within(8)
    run.expect_overshoot_below(10.0)


def test_a_lost_voltage_command_is_reported_and_recovered(hil_run):
    # the drive's voltage command of the period after the step is dropped on its way to the plant
    run = hil_run(
        SCENARIO,
        {
            "scenario.expect": "frames_lost",
            "drive.command_timeout_us": 2000000,  # hold the last command when none came
        },
        faults=[{"kind": "drop", "frame": "drive.TPDO1", "at_period": 21}],
    )
    run.expect_status("frames_lost")
    run.expect_settles_within(15)
    assert run.summary["bus_stats"]["missing_commands"] == 1
