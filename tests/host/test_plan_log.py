"""`bench plan --from-log`: a run's frames replayed onto a simulated bus, against hand-computed schedules, the
worst-case formula on a real direct run's frames, and the CLI's refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from bench_cli import bench_cli

from bench.paths import REPO
from bench.tools.plan import make_plan
from bench.tools.plan_log import simulate, simulate_period

US = 1e-6
EIGHT = "0011223344556677"
# Hand log, default node-IDs (plant 0x10, drive 0x20): SYNC 0x080, plant TPDO1/2 0x190/0x290 (the drive's RPDOs),
# drive TPDO1 0x210 (the plant's RPDO), plant EMCY 0x090, plant heartbeat 0x710, SDO request to the plant 0x610.
HAND_LOG = f"""(0.000000) vcan0 000#0110
(0.000000) vcan0 610#2B17100064000000
(1.000000) vcan0 080#01
(1.000010) vcan0 190#{EIGHT}
(1.000020) vcan0 290#{EIGHT}
(1.000030) vcan0 210#{EIGHT}
(1.001000) vcan0 080#02
(1.001001) vcan0 710#05
(1.001002) vcan0 090#{EIGHT}
(1.001010) vcan0 190#{EIGHT}
(1.001020) vcan0 290#{EIGHT}
(1.001030) vcan0 210#{EIGHT}
(1.002000) vcan0 080#03
(1.002010) vcan0 290#{EIGHT}
(1.002011) vcan0 610#{EIGHT}
(1.002020) vcan0 190#{EIGHT}
(1.002030) vcan0 210#{EIGHT}
(1.002040) vcan0 5A0#6017100000000000
"""


def _write(tmp: Path, text: str) -> Path:
    log = tmp / "bus.log"
    log.write_text(text)
    return log


def test_hand_made_log_schedule(tmp_path: Path) -> None:
    """Worst-case stuffing at 1 Mbit/s (1 us a bit): 1 data byte 65 bits, 8 bytes 135 (47 + 8n + (34 + 8n - 1)
    // 4). Latency plant 10 us, drive 20 us; Ts 600 us.
    Period 0: SYNC 0..65; plant TPDOs queued at 75: 0x190 75..210, 0x290 210..345; command queued at 365:
      365..500.
    Period 1: SYNC, heartbeat 0x710 and EMCY 0x090 pending at 0. SYNC 0..65; EMCY (the lower identifier of the
      two pending) 65..200; at 200 0x190 (queued at 75) beats the heartbeat: 200..335, 0x290 335..470; the
      command is queued at 490: the heartbeat takes the idle bus 470..535, the command 535..670.
    Period 2: the log has 0x290 before 0x190 and an SDO 0x610 queued at 0. SYNC 0..65; the SDO takes the bus
      at 65 (the plant's frames come at 75; it is not interrupted) 65..200; 0x190 first (lower id) 200..335,
      0x290 335..470; command 490..625. The SDO answer 0x5A0 after the last loop frame is the teardown."""
    plan = simulate(_write(tmp_path, HAND_LOG), 1e6, None, 600 * US, {"plant": 10 * US, "drive": 20 * US}, 0.8, True)
    assert (plan.left_out_before, plan.left_out_after, len(plan.periods)) == (2, 1, 3)
    bus = [p.bus_time_s / US for p in plan.periods]
    assert bus == pytest.approx([500, 670, 625])
    assert [p.chain_end_s / US for p in plan.periods] == pytest.approx([500, 670, 625])
    busy = [65 + 3 * 135, 65 + 3 * 135 + 135 + 65, 65 + 4 * 135]
    assert [p.load for p in plan.periods] == pytest.approx([b / 600 for b in busy])
    assert [p.fits for p in plan.periods] == [True, False, False]
    assert plan.overruns == 2 and plan.over_load == 2  # 470/600 = 0.78 <= 0.8; 670/600, 605/600 above
    assert plan.longer_than_ts == 2 and plan.no_command == 0  # 670 and 625 us of frames in a 600 us period
    assert plan.bus_time_s.p50 / US == pytest.approx(625)
    assert plan.bus_time_s.p99 / US == pytest.approx(625 + 0.98 * (670 - 625))  # linear between the top two
    assert plan.bus_time_s.max / US == pytest.approx(670)


def test_arbitration_order_lowest_identifier_first() -> None:
    """Period 2 of the hand log as sent: frames (id, us) in log order; 0x290 is listed before 0x190, both
    pending at 200 us: 0x190 goes first."""
    frames = [(0x080, 65 * US), (0x290, 135 * US), (0x610, 135 * US), (0x190, 135 * US), (0x210, 135 * US)]
    kinds = ["sync", "measurement", "other", "measurement", "command"]
    sim = simulate_period(frames, kinds, {"plant": 10 * US, "drive": 20 * US})
    assert [(i, round(a / US), round(b / US)) for i, a, b in sim.order] == [
        (0, 0, 65),
        (2, 65, 200),
        (3, 200, 335),
        (1, 335, 470),
        (4, 490, 625),
    ]


def test_hand_made_fd_log(tmp_path: Path) -> None:
    """FD frames (`id##1data`: bit-rate switch) at 1/5 Mbit/s, worst case: 34 nominal bits; 1 byte 1 + 4 + 8 +
    3 + 4 + 17 + 6 = 43 data bits; 8 bytes 1 + 4 + 64 + 17 + 4 + 17 + 6 = 113."""
    log = _write(tmp_path, f"(1.0) vcan0 080##101\n(1.0) vcan0 190##1{EIGHT}\n")
    plan = simulate(log, 1e6, 5e6, 100 * US, None, 0.8, True)
    assert plan.periods[0].bus_time_s / US == pytest.approx(34 + 43 / 5 + 34 + 113 / 5)
    with pytest.raises(ValueError, match="CAN FD frames"):
        simulate(log, 1e6, None, 100 * US)


@pytest.fixture(scope="module")
def direct_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run")
    bench_cli("run", REPO / "scenarios/you2019_step.toml", "--bus", "direct", "--no-viewer", "--out", out, expect=0)
    return out


def _no_stuff_s(bitrate: float, data_bitrate: float | None) -> float:
    """The formula's time for today's frames (SYNC with a 1-byte counter, 5 eight-byte PDOs: 3 of the loop, 2
    trace) without the stuff bits it assumes: classic (34 + 8n - 1) // 4; FD 4 in the arbitration phase and
    (5 + 8n - 1) // 4 in the data phase. On a CAN FD bus the SYNC stays classic (the bench's 0x2105 switches the
    PDOs only)."""
    sync = (47 + 8) / bitrate
    if data_bitrate is None:
        return sync + 5 * (47 + 64) / bitrate
    eight = (34 - 4) / bitrate + (1 + 4 + 64 + 4 + 17 + 6) / data_bitrate
    return sync + 5 * eight


@pytest.mark.parametrize("bitrate, data_bitrate", [(1e6, None), (1e6, 5e6), (2e6, 8e6)])
def test_direct_run_against_the_formula(direct_run: Path, bitrate: float, data_bitrate: float | None) -> None:
    log = direct_run / "bus.log"
    ts = json.loads((direct_run / "summary.json").read_text())["Ts_s"]
    exact = simulate(log, bitrate, data_bitrate, ts)
    worst = simulate(log, bitrate, data_bitrate, ts, worst=True)
    formula = make_plan(bitrate, ts, data_bitrate is not None, data_bitrate, trace_pdos=2).time_per_period_s
    loop_only = [n for n, p in enumerate(exact.periods) if p.frames == 6]  # SYNC, 2 plant, 3 drive TPDOs
    assert len(loop_only) > 150
    for n in loop_only:
        bus = exact.periods[n].bus_time_s
        assert _no_stuff_s(bitrate, data_bitrate) - 1e-12 <= bus <= formula + 1e-12
        assert abs(worst.periods[n].bus_time_s - formula) <= 6 / bitrate


def test_cli_from_log(direct_run: Path) -> None:
    res = bench_cli("plan", "--from-log", direct_run / "bus.log", "--json", expect=0)
    d = json.loads(res.stdout)
    summary = json.loads((direct_run / "summary.json").read_text())
    assert d["ts_s"] == summary["Ts_s"] and len(d["periods"]) == summary["periods"]
    assert d["left_out_before"] > 0 and d["latency_s"] == {"plant": 0.0, "drive": 0.0}
    assert d["extra_tpdos"] == 2 and d["formula_s"] == pytest.approx((65 + 5 * 135) * US)  # 1 Mbit/s, 2 trace PDOs
    text = bench_cli("plan", "--from-log", direct_run / "bus.log", "--fd", "--data-bitrate", "5e6").stdout
    assert "CAN FD 1/5" in text and "bench plan's formula" in text
    lat = bench_cli("plan", "--from-log", direct_run / "bus.log", "--latency-us", "drive=7", "--json", expect=0)
    assert json.loads(lat.stdout)["latency_s"]["drive"] == pytest.approx(7e-6)
    helptext = bench_cli("plan", "--help", expect=0).stdout
    assert "--from-log" in helptext and "arbitration" in helptext and "--latency-us" in helptext


@pytest.mark.parametrize(
    "extra, field",
    [
        (["--latency-us", "drive=-1"], "--latency-us"),
        (["--latency-us", "motor=5"], "--latency-us"),
        (["--latency-us", "plant=abc"], "--latency-us"),
        (["--ts", "-1"], "--ts"),
        (["--bitrate", "2e6"], "--bitrate"),
        (["--fd"], "--data-bitrate"),
        (["--max-load", "0"], "--max-load"),
        (["--data-bitrate", "8e6"], "--data-bitrate"),  # without --fd: a classic bus has one rate
        (["--fd", "--bitrate", "1e6", "--data-bitrate", "5e5"], "--data-bitrate"),  # below the nominal rate
    ],
)
def test_cli_bad_numbers(tmp_path: Path, extra: list[str], field: str) -> None:
    log = _write(tmp_path, HAND_LOG)
    bad = bench_cli("plan", "--from-log", log, "--ts", "1e-3", *extra, expect=2)
    assert bad.stderr.startswith(f"bench plan: {field} = ") and "must" in bad.stderr, bad.stderr
    assert "Traceback" not in bad.stderr and bad.stdout == ""


def test_cli_refusals(tmp_path: Path) -> None:
    missing = bench_cli("plan", "--from-log", tmp_path / "nothere.log", "--ts", "1e-4", expect=2)
    assert "--from-log" in missing.stderr and "no such file" in missing.stderr
    no_sync = bench_cli("plan", "--from-log", _write(tmp_path, "(1.0) vcan0 190#00\n"), "--ts", "1e-4", expect=2)
    assert "no SYNC" in no_sync.stderr and "0x080" in no_sync.stderr
    no_ts = bench_cli("plan", "--from-log", _write(tmp_path, HAND_LOG), expect=2)  # no summary.json beside it
    assert no_ts.stderr.startswith("bench plan: --ts = ") and "summary.json" in no_ts.stderr
    alone = bench_cli("plan", "--latency-us", "drive=1", expect=2)
    assert "--from-log" in alone.stderr
    traced = bench_cli("plan", "--from-log", _write(tmp_path, HAND_LOG), "--ts", "1e-3", "--trace-pdos", "2", expect=2)
    assert "--trace-pdos" in traced.stderr and "the run's own" in traced.stderr
    for res in (missing, no_sync, no_ts, alone, traced):
        assert res.stdout == "" and "Traceback" not in res.stderr


def test_a_scenarios_own_frames(direct_run: Path) -> None:
    """--scenario: the frames of the scenario's own mapping (its two trace PDOs on: 6 a period, where the EDS
    defaults have 4), the same as --from-log of a direct run of it (direct runs are deterministic)."""
    scen = json.loads(bench_cli("plan", "--scenario", REPO / "scenarios/you2019_step.toml", "--json", expect=0).stdout)
    log = json.loads(bench_cli("plan", "--from-log", direct_run / "bus.log", "--json", expect=0).stdout)
    for d in (scen, log):
        d.pop("log"), d.pop("ts_from")
    assert scen == log
    assert make_plan(1e6, scen["ts_s"]).time_per_period_s < scen["bus_time_s"]["p50"]  # more frames than the defaults
    refused = bench_cli("plan", "--scenario", REPO / "scenarios/you2019_step.toml", "--set", "scenario.periods=-1")
    assert refused.returncode == 2 and "scenario.periods = -1" in refused.stderr, refused.stderr
    both = bench_cli("plan", "--scenario", REPO / "scenarios/you2019_step.toml", "--from-log", direct_run / "bus.log")
    assert both.returncode == 2 and "--scenario and --from-log" in both.stderr


def test_a_period_without_its_command_never_fits(tmp_path: Path) -> None:
    """The hand log's first period without its command frame (a lost one): its chain would end at the last
    measurement (345 us, well inside Ts), but a period without its command is counted as such, never as fitting."""
    lost = HAND_LOG.replace(f"(1.000030) vcan0 210#{EIGHT}\n", "")
    plan = simulate(_write(tmp_path, lost), 1e6, None, 600 * US, {"plant": 10 * US, "drive": 20 * US}, 0.8, True)
    first = plan.periods[0]
    assert not first.has_command and not first.fits and first.chain_end_s / US == pytest.approx(345)
    assert plan.no_command == 1 and [p.has_command for p in plan.periods] == [False, True, True]


def test_a_run_at_other_node_ids(tmp_path: Path) -> None:
    """A run at plant node-ID 0x11: summary.json records its node_ids, the simulation takes them from there and
    finds the loop's frames at those IDs (the command ends before the period's last frame, the trace PDOs)."""
    out = tmp_path / "run"
    bench_cli("run", REPO / "scenarios/you2019_step.toml", "--bus", "direct", "--no-viewer", "--plant-id", "0x11",
              "--out", out, expect=0)  # fmt: skip
    assert json.loads((out / "summary.json").read_text())["node_ids"] == {"plant": 0x11, "drive": 0x20}
    plan = json.loads(bench_cli("plan", "--from-log", out / "bus.log", "--json", expect=0).stdout)
    assert plan["node_ids"] == {"plant": 0x11, "drive": 0x20} and plan["node_ids_from"] == "summary.json"
    assert plan["chain_end_s"]["p50"] < plan["bus_time_s"]["p50"]


def test_a_remote_frame_is_counted_as_sent() -> None:
    """A remote frame (a node guarding request, RTR 1 with its DLC) is a classic frame on either bus, its RTR bit and
    DLC as the log has them: not the data frame of 0 bytes, not an FD frame."""
    import can

    from bench.tools.plan_log import WireCache
    from bench.tools.wire import classic_stream

    rtr = can.Message(arbitration_id=0x70A, is_extended_id=False, is_remote_frame=True, dlc=1)
    want = classic_stream(0x70A, b"", remote=True, dlc=1).wire()
    for fd in (False, True):
        got = WireCache(fd, worst=False).bits(rtr)
        assert got == want and got.data == 0, (fd, got)  # no data-phase bits: no bit-rate switch
    assert want != classic_stream(0x70A, b"").wire()  # the RTR bit and the DLC change the stuffing and the CRC


@pytest.mark.parametrize("bitrate, data_bitrate", [(1e6, None), (2e6, 8e6)])
def test_a_run_without_sync_frames_is_cut_at_its_measurement_frame(
    tmp_path_factory: pytest.TempPathFactory, bitrate: float, data_bitrate: float | None
) -> None:
    """[frames] period_mark = "measurement", no trace PDOs: no SYNC on the bus, each period is the plant's compact
    frame (0x190) and the drive's command; at the worst case of stuffing each such period is the formula's."""
    out = tmp_path_factory.mktemp("marked")
    sets = ("--set", "frames.measurement=compact", "--set", "frames.period_mark=measurement", "--set", "trace={}")
    bench_cli("run", REPO / "scenarios/you2019_step.toml", "--bus", "direct", "--no-viewer", "--out", out, *sets,
              expect=0)  # fmt: skip
    ts = json.loads((out / "summary.json").read_text())["Ts_s"]
    worst = simulate(out / "bus.log", bitrate, data_bitrate, ts, worst=True)
    assert worst.mark == "mark (0x190)" and len(worst.periods) == 200
    formula = make_plan(bitrate, ts, data_bitrate is not None, data_bitrate, frames="compact",
                        period_mark="measurement").time_per_period_s  # fmt: skip
    loop_only = [p for p in worst.periods if p.frames == 2]
    assert len(loop_only) > 190
    for p in loop_only:
        assert abs(p.bus_time_s - formula) <= 2 / bitrate
    res = bench_cli("plan", "--from-log", out / "bus.log", expect=0)
    assert "mark->command end" in res.stdout and "after the next mark (0x190)" in res.stdout
