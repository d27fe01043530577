"""One step, two current laws, one pytest session: your own law's folder (hil_run's law=: built once per
session, selected at the start because the scenario names no law) and a law the drive ships (You 2019's
deadbeat, by controller.controller). The same test runs over both by pytest's parametrization.

The bounds are the laws' designs, as the bench measures them (`bench run scenarios/law_step.toml --bus direct
--law ../laws/complex_vector_pi --set controller.controller=complex_vector_pi`): the complex vector PI of
examples/laws settles in 9 periods with 4.9 % overshoot (its design: 4.92 %, 9); the deadbeat in 2, with none.
"""

from pathlib import Path

import pytest

HERE = Path(__file__).parent
SCENARIO = HERE / "scenarios" / "law_step.toml"
MY_LAW = HERE.parent / "laws" / "complex_vector_pi"  # a law folder of your own: C files and law.eds


@pytest.mark.parametrize(
    ("law", "overrides", "settle", "overshoot_pct"),
    [
        pytest.param(MY_LAW, {}, 10, 6.0, id="complex_vector_pi"),
        pytest.param(None, {"controller.controller": "deadbeat_you2019"}, 2, 0.5, id="deadbeat_you2019"),
    ],
)
def test_each_law_meets_its_design(hil_run, law, overrides, settle, overshoot_pct):
    run = hil_run(SCENARIO, overrides, law=law)
    run.expect_status("ok").expect_settles_within(settle).expect_overshoot_below(overshoot_pct)


@pytest.mark.hil(bus="vcan0")
def test_the_step_over_socketcan(hil_run):
    """Over vcan0 whatever --hil-bus says: skipped, the missing piece named, where this host cannot give it
    (no kernel CAN and no CAN box, no can-utils); pytest --hil-require makes that a failure."""
    run = hil_run(SCENARIO, {"controller.controller": "deadbeat_you2019"})
    run.expect_status("ok").expect_settles_within(2)
