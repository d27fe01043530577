"""Shared pytest set-up.

Tests under tests/can/ need a real SocketCAN vcan0. They run on the host when its
kernel has CAN, otherwise `scripts/run_tests.sh` runs them inside the virtme-ng
VM. A CAN test never skips for lack of a bus: it fails.
"""

from __future__ import annotations

from pathlib import Path

import pytest

CAN_DIR = Path(__file__).parent / "can"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if CAN_DIR in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.can)
