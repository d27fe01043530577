"""Which accelerator a CAN box boots with (bench/run/bus/box/accel.py): KVM when its device is usable and it has not
failed on this host (same kernel, same QEMU) before, else TCG; `--accel kvm` tries again, `--accel tcg` never tries.
The boot itself, a KVM attempt stopped at its deadline and the box up on TCG, is in tests/host/test_box.py."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from bench_cli import bench_cli

from bench.run.bus.box import accel


@pytest.fixture
def device(tmp_path: Path) -> Path:
    dev = tmp_path / "kvm"
    dev.write_bytes(b"")  # stands for /dev/kvm: present, readable and writable
    return dev


def test_a_usable_device_is_tried_unless_tcg_is_asked_for(tmp_path: Path, device: Path) -> None:
    assert accel.plan(tmp_path, "auto", device) == accel.Plan(True, f"{device} is usable")
    assert accel.plan(tmp_path, "kvm", device).try_kvm
    tcg = accel.plan(tmp_path, "tcg", device)
    assert not tcg.try_kvm and "TCG asked for" in tcg.why


def test_no_device_means_tcg_and_says_which_device(tmp_path: Path) -> None:
    missing = tmp_path / "no-kvm"
    for asked in ("auto", "kvm"):
        plan = accel.plan(tmp_path, asked, missing)
        assert not plan.try_kvm and f"{missing} does not exist" in plan.why


def test_a_recorded_failure_skips_kvm_until_the_host_changes_or_kvm_is_asked_for(tmp_path: Path, device: Path) -> None:
    accel.record_failure(tmp_path, "QEMU ended: failed to set MSR 0x10a")
    auto = accel.plan(tmp_path, "auto", device)
    assert not auto.try_kvm
    assert "failed on this host before (QEMU ended: failed to set MSR 0x10a)" in auto.why
    assert "--accel kvm" in auto.why
    assert accel.plan(tmp_path, "kvm", device).try_kvm  # asked for: tried again
    rec = json.loads((tmp_path / accel.RECORD).read_text())
    rec["host"]["kernel"] = "another-kernel"  # a new kernel (or QEMU) may work: tried again
    (tmp_path / accel.RECORD).write_text(json.dumps(rec))
    assert accel.plan(tmp_path, "auto", device).try_kvm
    accel.record_failure(tmp_path, "no guest within 30 s")
    accel.forget_failure(tmp_path)  # a KVM boot that worked forgets it
    assert accel.plan(tmp_path, "auto", device).try_kvm


def test_a_bad_choice_or_deadline_names_the_variable_and_what_it_takes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(accel.ACCEL_ENV, "hvf")
    with pytest.raises(ValueError, match=r"BENCH_BOX_ACCEL='hvf': the accelerator is one of auto, kvm, tcg"):
        accel.choice()
    assert accel.choice("tcg") == "tcg"  # the command line's wins
    monkeypatch.delenv(accel.ACCEL_ENV)
    assert accel.choice() == "auto"
    for bad in ("0", "-3", "soon"):
        monkeypatch.setenv(accel.DEADLINE_ENV, bad)
        with pytest.raises(ValueError, match=r"BENCH_BOX_KVM_DEADLINE_S=.*: seconds, > 0"):
            accel.deadline_s()
    monkeypatch.setenv(accel.DEADLINE_ENV, "12.5")
    assert accel.deadline_s() == 12.5


def test_bench_box_up_refuses_an_unknown_accelerator_before_booting() -> None:
    res = bench_cli("box", "up", "--accel", "hvf", expect=2)
    assert "invalid choice: 'hvf'" in res.stderr
    res = bench_cli("box", "up", env={**os.environ, accel.ACCEL_ENV: "hvf"}, expect=1)
    assert "BENCH_BOX_ACCEL='hvf'" in res.stderr


def test_bench_box_up_refuses_a_bad_kvm_deadline_before_booting() -> None:
    res = bench_cli("box", "up", env={**os.environ, accel.DEADLINE_ENV: "soon"}, expect=1)
    assert "bench box up: BENCH_BOX_KVM_DEADLINE_S='soon': seconds, > 0" in res.stderr, res.stderr
    assert "starting the CAN box" not in res.stderr
