"""Shared pytest set-up.

Tests under tests/can/ need a real SocketCAN vcan0. They run on the host when its
kernel has CAN, otherwise `scripts/run_tests.sh` runs them inside the virtme-ng
VM. A CAN test never skips for lack of a bus: it fails.

The tests run the bench as its users do: its command line through tests/bench_cli.py (bench_cli, spawn_bench:
`python -m bench.cli ...` in a child process), a scenario whose result they read through the plugin's hil_run
fixture (bench/pytest_plugin, enabled by the package's pytest11 entry point).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

CAN_DIR = Path(__file__).parent / "can"
# Host tests that share one resource of the machine run one after another in one pytest-xdist worker
# (scripts/run_tests.sh runs the host phase with `-n 2 --dist loadgroup`; each group is one unit of work):
# those that use the CAN box (one VM for the machine: test_box.py kills and restarts it) or the MCU image's
# build, and those that build in the repository's tree with make.
SERIAL = {
    "test_box.py": "box",  # boots, kills and stops the CAN box
    "test_hil_cancel.py": "box",  # pytest sessions that boot the CAN box and are cancelled
    # a user's project: pip builds the wheel in build/setuptools; its installed bench has a working folder and a CAN box
    # of its own (BENCH_CACHE_DIR), so it runs beside the box group, not in it (that group is the phase's longest)
    "test_user_project.py": "pip",
    "test_reproduce_report.py": "box",  # the claims of a paper over vcan0 through the box
    "test_example_law.py": "box",  # runs over vcan0 and the MCU image through the box
    "test_mcu_in_the_loop.py": "box",  # the MCU image over vcan0 through the box
    "test_mcu_image.py": "box",  # make mcu, the image in QEMU
    "test_fuzz.py": "make",  # make fuzz (two tests, one target)
    "test_law_folders.py": "make",  # make LAW=... builds, their failures and the old folders' removal
    "test_user_law.py": "make",  # a user's law built by make
}


# The "box" group's files in the order they run: the MCU image's own VMs first (the box down), then those that only use
# the box (one boot for the three), then those that kill, stop and boot it (test_box.py's fixture finds it up).
BOX_ORDER = (
    "test_mcu_image.py",
    "test_mcu_in_the_loop.py",
    "test_reproduce_report.py",
    "test_example_law.py",
    "test_box.py",
    "test_hil_cancel.py",
)

assert set(BOX_ORDER) == {f for f, g in SERIAL.items() if g == "box"}, "a file of the box group without its place"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if CAN_DIR in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.can)

    def rank(item: pytest.Item) -> int:  # a stable sort: the other files keep their order, before the box group's
        name = Path(str(item.fspath)).name
        return BOX_ORDER.index(name) if name in BOX_ORDER else -1

    items.sort(key=rank)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """`--dist loadgroup`: each SERIAL group's tests one unit of work, every other file its own. By file name
    in the controller, not by xdist_group marks: pytest-xdist 3.8.0 groups by rewriting node IDs, which pytest
    9.2 no longer lets it do (pytest-dev/pytest-xdist#1386: the marks are ignored and nothing says so)."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SerialFiles(LoadScopeScheduling):  # type: ignore[misc]
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]  # a file's tests stay together (its module fixtures built once)
            return SERIAL.get(Path(path).name, path)

    return SerialFiles(config, log)
