"""`bench plan`: frame lengths against hand-counted worst cases, and the CLI as a user runs it."""

from __future__ import annotations

import json

import pytest
from bench_cli import bench_cli

from bench.canbus import classic_frame_bits, fd_frame_bits
from bench.tools.plan import make_plan


def test_classic_frame_bits_worst_case() -> None:
    # 8 data bytes: 1 SOF + 11 ID + RTR + IDE + r0 + 4 DLC + 64 data + 15 CRC = 98 stuffable bits
    # (34 + 64), at most one stuff bit per 4 after the first: 24; + CRC delim, ACK, ACK delim, 7 EOF, 3 IFS = 13.
    assert classic_frame_bits(8) == 98 + 24 + 13
    assert classic_frame_bits(0) == 34 + 8 + 13
    with pytest.raises(ValueError):
        classic_frame_bits(9)


def test_fd_frame_is_shorter_in_time_at_5mbit() -> None:
    nominal, data = fd_frame_bits(8)
    assert nominal == 34
    assert nominal / 1e6 + data / 5e6 < classic_frame_bits(8) / 1e6


def test_classic_1mbit_cannot_carry_55us() -> None:
    plan = make_plan(1e6, 55e-6)
    assert not plan.fits
    assert plan.bits_per_period == 65 + 3 * 135  # SYNC with counter + 3 eight-byte PDOs
    assert plan.fastest_period_s == pytest.approx(470e-6 / 0.8)
    assert plan.bus_load == pytest.approx(470e-6 / 55e-6)


def test_slow_period_fits() -> None:
    assert make_plan(1e6, 1e-3).fits


def test_cli_json_and_errors() -> None:
    res = bench_cli("plan", "--bitrate", "1000000", "--ts", "55e-6", "--json", expect=0)
    d = json.loads(res.stdout)
    assert d["fits"] is False and d["bits_per_period"] == 470 and d["fastest_period_s"] > 55e-6
    bad = bench_cli("plan", "--ts", "-1", expect=2)
    assert "--ts" in bad.stderr
    text = bench_cli("plan", "--bitrate", "1000000", "--ts", "55e-6").stdout
    assert "fits in real time: NO" in text and "lockstep" in text


@pytest.mark.parametrize(
    "args, field",
    [
        (["--ts", "0"], "--ts"),
        (["--ts", "nan"], "--ts"),
        (["--ts", "inf"], "--ts"),
        (["--bitrate", "0"], "--bitrate"),
        (["--bitrate", "2e6"], "--bitrate"),
        (["--max-load", "1.5"], "--max-load"),
        (["--max-load", "nan"], "--max-load"),
        (["--fd"], "--data-bitrate"),
        (["--trace-pdos", "-1"], "--trace-pdos"),
        (["--trace-decimation", "0"], "--trace-decimation"),
    ],
)
def test_cli_bad_input_exits_2_naming_the_field_and_range(args: list[str], field: str) -> None:
    """Bad input exits 2 (as every command's), with the field, its value and the allowed range; no traceback."""
    bad = bench_cli("plan", *args, expect=2)
    assert bad.stderr.startswith(f"bench plan: {field} = ") and "must be" in bad.stderr, bad.stderr
    assert "Traceback" not in bad.stderr


def test_frame_sets_of_issue_54() -> None:
    """The compact measurement frame drops the plant's TPDO2 (one 8-byte frame less: 135 bits), the measurement as
    the period's mark drops the SYNC too (65 bits, 1-byte counter): hand-counted from the worst-case frame lengths
    above; the 100 us row of issue 54's targets: classic <= 350 us, FD 1/5 <= 150 us, FD 2/8 fits 100 us."""
    default = make_plan(1e6, 100e-6)
    compact = make_plan(1e6, 100e-6, frames="compact")
    marked = make_plan(1e6, 100e-6, frames="compact", period_mark="measurement")
    assert default.bits_per_period - compact.bits_per_period == 135
    assert compact.bits_per_period - marked.bits_per_period == 65
    assert marked.bits_per_period == 2 * 135 and len(marked.frames) == 2
    assert marked.fastest_period_s <= 350e-6 < compact.fastest_period_s
    fd15 = make_plan(1e6, 100e-6, True, 5e6, frames="compact", period_mark="measurement")
    nominal, data = fd_frame_bits(8)
    assert fd15.time_per_period_s == pytest.approx(2 * (nominal / 1e6 + data / 5e6))
    assert fd15.fastest_period_s <= 150e-6
    assert make_plan(2e6, 100e-6, True, 8e6, frames="compact", period_mark="measurement").fits
    assert not make_plan(2e6, 100e-6, True, 8e6).fits


def test_cli_frame_set_options() -> None:
    res = bench_cli("plan", "--frames", "compact", "--period-mark", "measurement", "--json", expect=0)
    assert json.loads(res.stdout)["bits_per_period"] == 270
    bad = bench_cli("plan", "--period-mark", "measurement", expect=2)
    assert "--period-mark = measurement: must be used with --frames compact" in bad.stderr
    bad = bench_cli("plan", "--frames", "tiny", expect=2)
    assert "--frames" in bad.stderr and "default" in bad.stderr and "compact" in bad.stderr


def test_can_fd_plans_keep_the_sync_classic_and_carry_the_single_frame() -> None:
    """On a CAN FD bus the bench's SYNC stays a classic frame (0x2105 switches the PDOs only): the formula counts it
    at the nominal rate; the single CAN FD measurement frame is 16 bytes, the compact one 8."""
    single = make_plan(2e6, 100e-6, True, 8e6, frames="single_frame")
    sync = next(f for f in single.frames if f.what.startswith("SYNC"))
    assert sync.bits == classic_frame_bits(1) and sync.time_s == pytest.approx(classic_frame_bits(1) / 2e6)
    meas = next(f for f in single.frames if "single_frame" in f.what)
    nominal, data = fd_frame_bits(16)
    assert meas.data_bytes == 16 and meas.time_s == pytest.approx(nominal / 2e6 + data / 8e6)
    assert len(single.frames) == 3  # SYNC, the measurement, the command
    marked = make_plan(2e6, 100e-6, True, 8e6, frames="single_frame", period_mark="measurement")
    assert marked.fits and len(marked.frames) == 2
    with pytest.raises(ValueError, match="single_frame is 16 bytes"):
        make_plan(1e6, 100e-6, frames="single_frame")
