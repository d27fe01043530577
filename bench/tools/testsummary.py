"""Combine the JUnit XML files of the test phases into one verdict line.

Prints 'N passed, M failed, K skipped' and exits non-zero if anything failed or
errored, if a phase is missing or ran no test, or if any CAN test was skipped.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path


def main(paths: list[str]) -> int:
    passed = failed = skipped = 0
    problems: list[str] = []
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            problems.append(f"{path}: missing (the phase did not run)")
            continue
        root = ET.parse(path).getroot()
        cases = root.iter("testcase")
        n = 0
        for case in cases:
            n += 1
            if case.find("failure") is not None or case.find("error") is not None:
                failed += 1
            elif case.find("skipped") is not None:
                skipped += 1
                if "can" in path.stem:
                    problems.append(f"CAN test skipped: {case.get('classname')}.{case.get('name')}")
            else:
                passed += 1
        if n == 0:
            problems.append(f"{path}: no test ran")
    print(f"{passed} passed, {failed} failed, {skipped} skipped")
    for p in problems:
        print(f"problem: {p}")
    return 1 if failed or problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
