"""RerunSink: the .rrd holds every period of every signal, grouped by unit, under a blueprint
with one view per unit; the served web viewer answers and outlives the run; a taken port is a
clear one-line error."""

from __future__ import annotations

import fnmatch
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from rrd_util import read_recording

from bench.signals import SignalInfo
from bench.view import rerun_sink
from bench.view.rerun_blueprint import entity_path, unit_slug, view_name
from bench.view.rerun_sink import RerunSink, ServeError

REPO = Path(__file__).resolve().parents[2]

# Signals of the three controllers (You 2019 deadbeat + online tuning, Yao 2020 DPCC, Zhao 2022),
# with the unit group and the view each must land in.
EXPECTED: dict[str, tuple[str, str]] = {
    "i_a_A": ("A", "currents (A)"),
    "iq_A": ("A", "currents (A)"),
    "iq_ref_A": ("A", "currents (A)"),
    "v_alpha_V": ("V", "voltages (V)"),
    "vq_V": ("V", "voltages (V)"),
    "K1_active_V_A": ("V_per_A", "gains (V/A)"),
    "L_hat_H": ("H", "inductances (H)"),
    "det_A2": ("A2", "squared currents (A²)"),
    "K1_hat_V_A": ("V_per_A", "gains (V/A)"),  # K1_hat had no unit and landed among the counts
    "sync_counter": ("count_or_ratio", "counts and ratios"),
    "Yao_2020_DPCC_R_hat_ohm": ("ohm", "resistances (Ω)"),
    "Yao_2020_DPCC_L_hat_H": ("H", "inductances (H)"),
    "Yao_2020_DPCC_dM_q_V": ("V", "voltages (V)"),
    "Zhao_2022_K1_V_A": ("V_per_A", "gains (V/A)"),
    "Zhao_2022_limited": ("count_or_ratio", "counts and ratios"),
    "true_omega_m_rad_s": ("rad_per_s", "speeds (rad/s)"),
}
SIGNALS = [SignalInfo.of(name, "test") for name in EXPECTED]


def make_run(n: int, first_period: int = 5, dt: float = 1e-4) -> dict[str, np.ndarray]:
    """A whole run as columns, with a NaN and an inf, integer and boolean columns."""
    rng = np.random.default_rng(7)
    period = np.arange(first_period, first_period + n, dtype=np.int64)
    run: dict[str, np.ndarray] = {"period": period, "t_s": period * dt}
    for name in EXPECTED:
        run[name] = rng.standard_normal(n)
    run["K1_active_V_A"] = 83.0 + 0.1 * rng.standard_normal(n)
    run["L_hat_H"] = 0.0045 + 1e-5 * rng.standard_normal(n)
    run["sync_counter"] = (period % 256).astype(np.uint8)
    run["Zhao_2022_limited"] = rng.random(n) < 0.2
    run["K1_hat_V_A"] = run["K1_hat_V_A"].astype(np.float32)
    run["L_hat_H"][3] = np.nan
    run["Yao_2020_DPCC_R_hat_ohm"][n // 2 : n // 2 + 7] = np.nan
    run["det_A2"][-1] = np.inf
    return run


def chunks_of(run: dict[str, np.ndarray], sizes: list[int]):
    start = 0
    for size in sizes:
        yield {k: v[start : start + size] for k, v in run.items()}
        start += size
    assert start == len(run["period"])


def read_blueprint_views(path: Path) -> list[dict[str, str]]:
    """The time-series views of the .rrd's blueprint: name, origin and content queries."""
    reader = RrdReader(path)
    assert reader.blueprints(), "no blueprint in the .rrd"
    fields: dict[str, dict[str, list]] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if ":" in name and not pa.types.is_timestamp(batch.schema.field(name).type):
                fields.setdefault(chunk.entity_path, {})[name] = batch.column(name).to_pylist()[-1]
    views = []
    for ent, f in fields.items():
        if ent.startswith("/view/") and not ent.endswith("/ViewContents"):
            queries = fields.get(ent + "/ViewContents", {}).get("ViewContents:query", ["$origin/**"])
            views.append(
                {
                    "class": f["ViewBlueprint:class_identifier"][0],
                    "name": f["ViewBlueprint:display_name"][0],
                    "origin": f["ViewBlueprint:space_origin"][0],
                    "queries": queries,
                }
            )
    return views


def view_matches(view: dict, entity: str) -> bool:
    for q in view["queries"]:
        q = q.replace("$origin", view["origin"])
        if q.startswith("+ ") or q.startswith("- "):
            q = q[2:]
        if q.endswith("/**") and (entity == q[:-3] or entity.startswith(q[:-3] + "/")):
            return True
        if fnmatch.fnmatchcase(entity, q):
            return True
    return False


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("", 0))
        return s.getsockname()[1]


# --- the .rrd --------------------------------------------------------------------------------------


def test_unit_slugs_and_view_names():
    assert [unit_slug(u) for u in ("A", "V", "V/A", "H", "Ω", "A²", "rad/s", "1", "rad/s²", "N·m", "Ω/(V·s)")] == [
        "A",
        "V",
        "V_per_A",
        "H",
        "ohm",
        "A2",
        "rad_per_s",
        "count_or_ratio",
        "rad_per_s2",
        "N_m",
        "ohm_per_V_s",
    ]
    assert view_name("A") == "currents (A)" and view_name("1") == "counts and ratios"
    assert view_name("furlong") == "furlong"
    assert entity_path(SignalInfo.of("Yao_2020_DPCC_R_hat_ohm", "x")) == "/ohm/Yao_2020_DPCC_R_hat_ohm"


def test_rrd_holds_every_period_of_every_signal_in_its_unit_view(tmp_path):
    n = 3000
    run = make_run(n)
    rrd = tmp_path / "run.rrd"
    sink = RerunSink("roundtrip", rrd)
    sink.begin(SIGNALS + [SignalInfo.of("period", "x"), SignalInfo.of("t_s", "x")])
    for chunk in chunks_of(run, [1024, 37, n - 1024 - 37]):
        sink.write(chunk)
    sink.end()
    assert sink.url is None

    got = read_recording(rrd)  # readable after end(), before close()
    assert set(got) == {f"/{slug}/{name}" for name, (slug, _) in EXPECTED.items()}
    expected_ns = np.round(run["t_s"] * 1e9).astype(np.int64)
    for name, (slug, _) in EXPECTED.items():
        g = got[f"/{slug}/{name}"]
        np.testing.assert_array_equal(g["period"], run["period"], err_msg=name)
        np.testing.assert_array_equal(g["value"], np.asarray(run[name], dtype=np.float64), err_msg=name)  # NaN == NaN
        assert np.max(np.abs(g["sim_time_ns"] - expected_ns)) <= 1, name
    assert np.isnan(got["/H/L_hat_H"]["value"][3])
    assert np.isnan(got["/ohm/Yao_2020_DPCC_R_hat_ohm"]["value"][n // 2 : n // 2 + 7]).all()
    assert np.isposinf(got["/A2/det_A2"]["value"][-1])

    views = read_blueprint_views(rrd)
    assert all(v["class"] == "TimeSeries" for v in views)
    assert len({v["name"] for v in views}) == len(views) == len({slug for slug, _ in EXPECTED.values()})
    for name, (slug, view) in EXPECTED.items():
        homes = [v["name"] for v in views if view_matches(v, f"/{slug}/{name}")]
        assert homes == [view], (name, homes)
    sink.close()
    sink.close()  # idempotent
    assert RrdReader(rrd).store() is not None  # the footer (manifest) is written


def test_live_stream_gets_every_nth_period_across_chunks(tmp_path):
    n = 1000
    run = make_run(n, first_period=0)
    sink = RerunSink("decimate", tmp_path / "full.rrd", live_decimate=7)
    live = rr.RecordingStream(rerun_sink.APPLICATION_ID, recording_id="decimate")
    memory = live.memory_recording()
    sink.live = live  # stands in for the viewer connection
    sink.begin(SIGNALS)
    for chunk in chunks_of(run, [3, 250, 1, 746]):
        sink.write(chunk)
    sink.end()
    live_rrd = tmp_path / "live.rrd"
    live_rrd.write_bytes(memory.drain_as_bytes())
    full, thin = read_recording(tmp_path / "full.rrd"), read_recording(live_rrd)
    assert set(thin) == set(full)
    for ent in full:
        np.testing.assert_array_equal(full[ent]["period"], np.arange(n))
        np.testing.assert_array_equal(thin[ent]["period"], np.arange(0, n, 7))
        np.testing.assert_array_equal(thin[ent]["value"], full[ent]["value"][::7])
    sink.close()


def test_missing_and_undeclared_columns_do_not_crash(tmp_path, capsys):
    rrd = tmp_path / "partial.rrd"
    sink = RerunSink("partial", rrd)
    sink.begin([SignalInfo.of("iq_A", "x"), SignalInfo.of("vq_V", "x")], None)  # as bench.run.sinks.Sink calls it
    p = np.arange(10)
    sink.write({"period": p, "t_s": p * 1e-4, "iq_A": p * 1.0, "extra_A": p * 2.0})
    sink.write({"period": p[:0], "t_s": p[:0] * 1.0, "iq_A": p[:0] * 1.0})  # an empty chunk
    sink.end({"periods": 10})
    sink.close()
    err = capsys.readouterr().err
    assert "vq_V is missing" in err and "extra_A was not declared" in err
    assert set(read_recording(rrd)) == {"/A/iq_A"}
    with pytest.raises(RuntimeError):
        sink.write({"period": p, "t_s": p * 1e-4, "iq_A": p * 1.0})


# --- serving ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """The one serve-mode sink of this test process (serving happens once per process)."""
    web, grpc = free_port(), free_port()
    sink = RerunSink(
        "served",
        tmp_path_factory.mktemp("serve") / "run.rrd",
        live="serve",
        live_decimate=10,
        web_port=web,
        grpc_port=grpc,
    )
    yield sink, web, grpc
    sink.close()


def get(url: str) -> tuple[int, str, bytes]:
    with urllib.request.urlopen(url, timeout=10) as resp:
        return resp.status, resp.headers.get("Content-Type", ""), resp.read()


def test_served_web_viewer_answers_during_and_after_the_run(served, capsys):
    sink, web, grpc = served
    assert sink.url == f"http://localhost:{web}/?url=rerun%2Bhttp://localhost:{grpc}/proxy"
    status, ctype, body = get(sink.url)
    assert status == 200 and "text/html" in ctype and b"<html" in body.lower()
    status, ctype, _ = get(f"http://localhost:{web}/re_viewer_bg.wasm")
    assert status == 200 and ctype == "application/wasm"

    run = make_run(2000, first_period=0)
    sink.begin(SIGNALS)
    for chunk in chunks_of(run, [1000, 555, 445]):
        sink.write(chunk)
    sink.end()
    assert get(sink.url)[0] == 200  # end() does not stop serving

    t0 = time.monotonic()
    sink.serve_until(0.5)
    elapsed = time.monotonic() - t0
    assert 0.45 <= elapsed < 2.0
    assert sink.url in capsys.readouterr().out
    assert get(sink.url)[0] == 200


@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_served_grpc_stream_holds_the_decimated_run(served, tmp_path):
    """What a browser would receive: download the gRPC server's content with the rerun CLI."""
    sink, web, grpc = served
    rerun_cli = Path(sys.executable).with_name("rerun")
    assert rerun_cli.exists(), "rerun-sdk installs its CLI next to the interpreter"
    if not sink._ended:  # noqa: SLF001 - the previous test did not run (e.g. -k)
        sink.begin(SIGNALS)
        for chunk in chunks_of(make_run(2000, first_period=0), [1000, 555, 445]):
            sink.write(chunk)
        sink.end()
    proc = subprocess.Popen(
        [str(rerun_cli), "download", "-o", str(tmp_path), f"rerun+http://127.0.0.1:{grpc}/proxy"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    got: dict = {}
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            time.sleep(0.3)
            try:
                got = read_recording(tmp_path / "output.rrd")
            except Exception:  # noqa: BLE001 - still being written
                continue
            if all(len(v["period"]) == 200 for v in got.values()) and len(got) == len(EXPECTED):
                break
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert len(got) == len(EXPECTED)
    for ent, v in got.items():
        np.testing.assert_array_equal(v["period"], np.arange(0, 2000, 10), err_msg=ent)


def test_second_serving_sink_reuses_same_ports_and_refuses_others(served, tmp_path):
    sink, web, grpc = served
    again = RerunSink("served-again", tmp_path / "again.rrd", live="serve", web_port=web, grpc_port=grpc)
    assert again.url == sink.url
    again.begin([SignalInfo.of("iq_A", "x")])
    p = np.arange(100)
    again.write({"period": p, "t_s": p * 1e-4, "iq_A": p * 1.0})
    again.close()
    assert get(sink.url)[0] == 200  # closing the second sink does not stop serving
    with pytest.raises(ServeError, match=f"already serves the web viewer at .*web port {web}"):
        RerunSink("elsewhere", None, live="serve", web_port=free_port(), grpc_port=free_port())


def test_headless_chromium_loads_the_served_page(served):  # chromium: installed by scripts/setup.sh
    sink, _, _ = served
    with tempfile.TemporaryDirectory() as profile:
        r = subprocess.run(
            [
                "/usr/bin/chromium",
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                f"--user-data-dir={profile}",
                "--dump-dom",
                sink.url,
            ],
            capture_output=True,
            text=True,
            timeout=20,
        )
    assert r.returncode == 0, r.stderr[-2000:]
    assert 'id="the_canvas_id"' in r.stdout and "re_viewer.js" in r.stdout


PORT_CONFLICT = r"""
import socket, sys
from bench.view.rerun_sink import RerunSink, ServeError
busy = socket.socket(); busy.bind(("127.0.0.1", 0)); busy.listen()
port = busy.getsockname()[1]
free = socket.socket(); free.bind(("", 0)); other = free.getsockname()[1]; free.close()
ports = dict(web_port=port, grpc_port=other) if sys.argv[1] == "web" else dict(web_port=other, grpc_port=port)
try:
    RerunSink("conflict", None, live="serve", **ports)
except ServeError as exc:
    print(exc)
    print("PORT", port)
    sys.exit(3)
print("no error")
"""


@pytest.mark.parametrize("which,option", [("grpc", "--grpc-port"), ("web", "--web-port")])
def test_port_in_use_is_one_clear_error(which, option):
    # A fresh process: this one already serves (once per process).
    r = subprocess.run(
        [sys.executable, "-c", PORT_CONFLICT, which],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert r.returncode == 3, r.stdout + r.stderr
    message, port_line = r.stdout.strip().splitlines()
    port = port_line.split()[1]
    assert f"port {port} is already in use" in message and option in message
    assert "ERROR" not in r.stderr and "Address already in use" not in r.stderr + message


def test_spawn_without_display_says_so_once_and_keeps_the_file(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(rerun_sink, "_SAID_NO_DISPLAY", False)
    monkeypatch.setattr(rerun_sink.sys, "platform", "linux")
    sinks = [RerunSink(f"spawn{i}", tmp_path / f"{i}.rrd", live="spawn") for i in range(2)]
    assert capsys.readouterr().out.count("no display") == 1
    for s in sinks:
        assert s.live is None
        s.begin([SignalInfo.of("iq_A", "x")])
        p = np.arange(5)
        s.write({"period": p, "t_s": p * 1e-4, "iq_A": p * 1.0})
        s.close()
    assert all(set(read_recording(tmp_path / f"{i}.rrd")) == {"/A/iq_A"} for i in range(2))
