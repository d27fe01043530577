from __future__ import annotations

import os

import pytest

# These tests run inside the VM and keep their runs in pytest's temporary folders there (the guest's own
# /tmp): on purpose, they read them back in the VM. A user's --out outside the folders the VM shares is
# refused (bench.paths.lost_in_vm); the tests' bench processes are told no folder list, so they write.
os.environ.pop("BENCH_VM_SHARED", None)

from bench.canbus import interface_state, probe_af_can


@pytest.fixture(scope="session")
def vcan0() -> str:
    """The name of an up vcan interface; fails (never skips) when there is none."""
    af = probe_af_can()
    if not af.af_can:
        pytest.fail(
            f"CAN test without SocketCAN ({af.detail}): run it through scripts/run_tests.sh "
            "or `bench vm -- pytest tests/can`"
        )
    state = interface_state("vcan0")
    if state != "up":
        pytest.fail(f"vcan0 is {state or 'absent'}: create it (ip link add dev vcan0 type vcan; ip link set up vcan0)")
    return "vcan0"
