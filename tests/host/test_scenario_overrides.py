"""A refusal an override caused names the override, with the nearest known key (issue 28: a user's typo in
hil_run's overrides or `bench run --set` was blamed on the scenario file); a refusal of the file itself is
still the file's."""

from __future__ import annotations

import pytest

from bench.paths import REPO
from bench.scenario import ScenarioError, loads

TEXT = (REPO / "scenarios" / "you2019_step.toml").read_text()


def test_a_misspelt_override_is_named_with_the_key_it_meant() -> None:
    with pytest.raises(ScenarioError) as err:
        loads(TEXT, "step.toml", ["scenario.periods=100", "controller.L_hat_ration=1.3"])
    text = str(err.value)
    assert text.startswith("--set controller.L_hat_ration=1.3 (on step.toml): unknown key"), text
    assert text.endswith("; did you mean controller.L_hat_ratio?"), text


def test_an_override_out_of_range_is_named() -> None:
    with pytest.raises(ScenarioError, match=r"^--set controller\.Vmax_V=-5 \(on step\.toml\): .*Vmax_V"):
        loads(TEXT, "step.toml", ["controller.Vmax_V=-5"])


def test_a_fault_of_the_file_is_the_files() -> None:
    bad = TEXT.replace('mech_mode = "locked"', 'mech_mod = "locked"')
    with pytest.raises(ScenarioError, match=r"^step\.toml: unknown key"):
        loads(bad, "step.toml", ["controller.L_hat_ratio=1.3"])
