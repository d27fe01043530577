#!/usr/bin/env bash
# The whole test suite, in two pytest phases, then one combined verdict:
#   1. host phase: everything that needs no CAN bus (C unit tests, models, CLI, fuzz ...), in two
#      pytest-xdist workers (tests/conftest.py's SERIAL files, which share the CAN box or build with
#      make in the tree, one after another in one of them)
#   2. CAN phase: tests/can/ over a real vcan0 - on the host when its kernel has
#      SocketCAN; otherwise on the host against one CAN box, but for the kernel_can tests
#      (the emulated CAN controllers), which run inside the virtme-ng VM (booted once for the phase).
# A CAN test that is skipped or deselected fails the run, as does a phase that
# collected no test.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
RES=build/test-results
rm -rf "$RES"; mkdir -p "$RES"
export PYTHONHASHSEED=0
# The CAN phase runs ~10 minutes on an idle machine, more with both cores busy: one line per test as it ends
# (-v: its name, PASSED/FAILED, the share done), the slowest tests at the end, and pytest's summary line ("N passed in ...", which
# .ci/run greps) still last. tests/host/test_progress.py runs pytest with these options.
CAN_PYTEST_OPTS=(-v --durations=15 -p no:cacheprovider)

echo "== host phase: pytest tests (without tests/can) =="
$PY -m pytest tests --ignore=tests/can -m "not can" -n 2 --dist loadgroup --junitxml="$RES/host.xml" -q "$@"
host_rc=$?

echo "== CAN phase: pytest tests/can over real vcan0 =="
if $PY -c 'from bench.canbus import host_has_vcan; import sys; sys.exit(0 if host_has_vcan() else 1)'; then
    echo "(host SocketCAN; the tests of CAN controllers (can0, can1 on one bus) run in the VM with emulated ones)"
    $PY -m pytest tests/can --ignore=tests/can/test_can_controllers.py --junitxml="$RES/can.xml" \
        "${CAN_PYTEST_OPTS[@]}" "$@"
    can_rc=$?
    .venv/bin/bench vm --timeout 1200 --can-controllers 2 -- $PY -m pytest tests/can/test_can_controllers.py \
        --junitxml="$RES/can_controllers.xml" "${CAN_PYTEST_OPTS[@]}" "$@" || can_rc=1
else
    # Every CAN test but the kernel_can ones runs here, with every line of Python on the host, against one CAN
    # box (docs/VM.md): the bench's own runs take slots of it, the tests' own processes and python-can bus one
    # more (tests/can/can_site.py). The kernel_can tests (the emulated CAN controllers can0/can1 on one bus, a
    # VM's devices) run inside one VM.
    echo "(host kernel has no SocketCAN: tests/can on the host against one CAN box, the kernel_can tests in the VM)"
    can_rc=0
    if .venv/bin/bench box up; then
        $PY -m pytest tests/can -m "not kernel_can" --junitxml="$RES/can_box.xml" "${CAN_PYTEST_OPTS[@]}" "$@" \
            || can_rc=1
    else
        can_rc=1
    fi
    .venv/bin/bench box down
    .venv/bin/bench vm --timeout 1200 --can-controllers 2 -- $PY -m pytest tests/can -m kernel_can \
        --junitxml="$RES/can.xml" "${CAN_PYTEST_OPTS[@]}" "$@" || can_rc=1
fi

# the CAN box a test may have left up (tests/host/test_box.py stops its own): no QEMU outlives the suite
.venv/bin/bench box down >/dev/null 2>&1 || true

$PY -m bench.tools.testsummary "$RES"/*.xml
sum_rc=$?
if [ $host_rc -ne 0 ] || [ $can_rc -ne 0 ] || [ $sum_rc -ne 0 ]; then
    echo "test suite FAILED (host phase rc=$host_rc, CAN phase rc=$can_rc, summary rc=$sum_rc)"
    exit 1
fi
echo "test suite passed"
