from __future__ import annotations

import os
from collections.abc import Iterator

import pytest
from can_site import Site

# The kernel_can tests run inside the VM and keep their runs in pytest's temporary folders there (the guest's
# own /tmp): on purpose, they read them back in the VM. A user's --out outside the folders the VM shares is
# refused (bench.paths.lost_in_vm); the tests' bench processes are told no folder list, so they write.
os.environ.pop("BENCH_VM_SHARED", None)

from bench.canbus import interface_state, probe_af_can
from bench.run.bus.buses import box_wanted


@pytest.fixture(autouse=True)
def _kernel_can_here(request: pytest.FixtureRequest) -> None:
    """A kernel_can test needs the kernel's CAN in this process: it fails (never skips) on a host without."""
    if request.node.get_closest_marker("kernel_can") is not None and not probe_af_can().af_can:
        pytest.fail(
            "a kernel_can test on a host without SocketCAN: it runs inside the VM "
            "(scripts/run_tests.sh, or `bench vm -- pytest -m kernel_can tests/can`)"
        )


@pytest.fixture(scope="session")
def vcan0() -> str:
    """The name of an up vcan interface, or vcan0 in the CAN box on a host without kernel CAN (for the tests
    that run the bench through its front doors: run_scenario, `bench run`, the claims); fails (never skips)
    when there is none."""
    af = probe_af_can()
    if not af.af_can and box_wanted("vcan0") is not None:
        return "vcan0"  # the runs' buses are in the CAN box (scripts/run_tests.sh runs these files on the host)
    if not af.af_can:
        pytest.fail(
            f"CAN test without SocketCAN ({af.detail}): run it through scripts/run_tests.sh "
            "or `bench vm -- pytest tests/can`"
        )
    state = interface_state("vcan0")
    if state != "up":
        pytest.fail(
            f"vcan0 is {state or 'absent'}: create it (ip link add dev vcan0 type vcan mtu 72; ip link set up vcan0)"
        )
    return "vcan0"


@pytest.fixture(scope="session")
def site(vcan0: str) -> Iterator[Site]:
    """Where a test's own C processes and python-can bus live (tests/can/can_site.py): the host's vcan0, or one
    slot of the CAN box held for the session on a host without kernel CAN."""
    if probe_af_can().af_can and interface_state(vcan0) == "up":
        yield Site(vcan0)
        return
    from bench.run.bus.box import lease

    held = lease.acquire((vcan0,))
    try:
        held.open_tap()  # the tests' python-can bus
        yield Site(vcan0, held)
    finally:
        held.close()
