"""The EDS files the bench writes load in the CANopen tools its users have (issue 52): the repository's EDS set
(protocols/generated/eds, the bench's EDS_DIR) and a user's law build's (gen_od.py --law DIR --out OUT, the step of
`make LAW=DIR` that writes build/laws/<name>-<hash>/eds/), each read by

- python canopen (the bench's own reader): no warning;
- canopen-monitor 4.1.0 (PyPI): its own EDS parser, the strictest here (a file in blocks split at blank lines, a
  block's first line its [section], every other line but a ';' comment key=value at each '='): every object and
  sub-index python canopen reads, with the same data types;
- Lely's dcf-tools 2.4.2 (PyPI; lely-core's Python EDS/DCF tools: dcfchk, dcf2dev): its checker finds nothing but
  the bench's own keys (Description, ValueNames, ...), its [EmergencyCodes] section and the REAL32 values, which
  Lely reads as the 32-bit pattern (0x3FB33333 for 1.4: lely-core's co_val_lex, dcf-tools' _parse_real32) where
  CiA 306 readers (python canopen, canopen-monitor, CANopenEditor) read a decimal number. With those values
  written Lely's way and the bench's keys left out, as a Lely user imports a file, it checks clean and its device
  model holds the objects and PDO maps python canopen reads.

The tools are installed once into a venv of their own under build/eds-tools/ (by their pinned versions); a tool
the package index does not have skips its test with the index's answer. Not testable here: Lely's C library
(lely-core is not packaged by Debian 12, and PyPI's `lely` is an unrelated project) and CANopenNode's EDS tool
(CANopenEditor, a .NET program published by no package index this machine reaches)."""

from __future__ import annotations

import configparser
import fcntl
import json
import logging
import re
import shutil
import struct
import subprocess
import sys
import venv
from pathlib import Path

import canopen
import pytest

from bench.paths import EDS_DIR, REPO
from bench.root import STATE

TOOLS = ("canopen-monitor==4.1.0", "dcf-tools==2.4.2")
TOOLS_DIR = STATE / "eds-tools"
EXAMPLE_LAW = REPO / "examples" / "laws" / "complex_vector_pi"
# what a law.eds of a user may hold that the merge must write so that every reader takes it
USER_EDITS = (
    ("[2400]\n", "; my law, written by hand\n# another comment style\n[2400]  ; the record\n"),
    ("[2400sub1]\n", "; the bandwidth, above its section\n[2400sub1]\n"),
    ("ParameterName=bandwidth_Hz", "ParameterName = bandwidth_Hz"),
)
# keys of the bench's own (CiA 306 has none of them; every CiA 306 reader may ignore them): Lely names them
BENCH_KEYS = {"Description", "ValueNames", "BitNames", "ValidIf", "NotApplicableNote", "CurrentLaws", "DefaultLaw"}
BENCH_KEYS |= {"Source", "Results", "Trace"}  # and their per-law forms Results.<law>=
REAL = {0x0008: ("<f", "<I", 8), 0x0011: ("<d", "<Q", 16)}
INDEX = re.compile(r"[0-9A-Fa-f]{4}(sub[0-9A-Fa-f]+)?\Z")

CANOPEN_MONITOR = """
import json, sys
from canopen_monitor.parse.eds import load_eds_file
def dt(x):  # a DataType as canopen-monitor keeps it: "0x0008" (its number conversion skips 0x-prefixed text)
    v = getattr(x, "data_type", None)
    return int(v, 0) if isinstance(v, str) else v
out = {}
for path in sys.argv[1:]:
    od = load_eds_file(path)
    out[path] = {int(k, 16): [sorted(v.sub_indices), dt(v), {s: dt(x) for s, x in v.sub_indices.items()}]
                 for k, v in od.indices.items()}
print(json.dumps(out))
"""
LELY = """
import json, sys, warnings
from dcf.device import Device
from dcf.lint import lint
from dcf.parse import parse_file
as_written, lely_way = sys.argv[1:3]
with warnings.catch_warnings(record=True) as found:
    warnings.simplefilter("always")
    lint(parse_file(as_written))
with warnings.catch_warnings(record=True) as again:
    warnings.simplefilter("always")
    clean = lint(parse_file(lely_way))
    dev = Device(parse_file(lely_way))
pdos = {f"{kind}{n}": [p.cob_id, [[s.index, s.sub_index] for s in p.mapping.values()]]
        for kind, table in (("rpdo", dev.rpdo), ("tpdo", dev.tpdo)) for n, p in table.items()}
print(json.dumps({"found": [str(w.message) for w in found], "clean": clean, "again": [str(w.message) for w in again],
                  "node_id": dev.node_id, "objects": {i: sorted(o) for i, o in dev.items()}, "pdos": pdos}))
"""


def _tools() -> Path:
    """The tools' venv (made once, under a lock: pytest-xdist's workers); skip when the index lacks a tool."""
    key = re.sub(r"[^0-9A-Za-z.]+", "-", "_".join(TOOLS))
    home = TOOLS_DIR / key
    py = home / "bin" / "python"
    TOOLS_DIR.mkdir(parents=True, exist_ok=True)
    with open(TOOLS_DIR / ".lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (home / "installed").is_file():
            return py
        shutil.rmtree(home, ignore_errors=True)
        venv.EnvBuilder(with_pip=True).create(home)
        res = subprocess.run(
            [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", *TOOLS],
            capture_output=True,
            text=True,
            timeout=900,
        )
        if res.returncode != 0:
            shutil.rmtree(home, ignore_errors=True)
            said = res.stdout + res.stderr
            if "No matching distribution found" in said:  # the index does not have it: nothing to test with
                pytest.skip(f"the package index has no {', '.join(TOOLS)}: {said.strip().splitlines()[-1]}")
            raise AssertionError(f"pip install {' '.join(TOOLS)} failed:\n{said[-3000:]}")
        (home / "installed").write_text("\n".join(TOOLS) + "\n")
    return py


@pytest.fixture(scope="module")
def tools() -> Path:
    return _tools()


@pytest.fixture(scope="module")
def eds_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The repository's EDS set and a user's law build's drive.eds (the example law, edited as a user might)."""
    tmp = tmp_path_factory.mktemp("eds")
    law = tmp / "my_law"
    shutil.copytree(EXAMPLE_LAW, law)
    text = (law / "law.eds").read_text()
    for old, new in USER_EDITS:
        assert old in text, old
        text = text.replace(old, new, 1)
    (law / "law.eds").write_text(text)
    out = tmp / "build"
    res = subprocess.run(
        [sys.executable, str(REPO / "protocols" / "gen_od.py"), "--law", str(law), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 0, res.stderr
    return {"drive": EDS_DIR / "drive.eds", "plant": EDS_DIR / "plant.eds", "user law": out / "eds" / "drive.eds"}


def _canopen(path: Path, node_id: int | None = None) -> canopen.ObjectDictionary:
    handler = logging.Handler()
    seen: list[str] = []
    handler.emit = lambda record: seen.append(record.getMessage())  # type: ignore[method-assign]
    logging.getLogger("canopen").addHandler(handler)
    try:
        od = canopen.import_od(str(path), node_id=node_id)
    finally:
        logging.getLogger("canopen").removeHandler(handler)
    assert not seen, f"{path}: canopen warned: {seen[:3]}"
    return od


def _objects(od: canopen.ObjectDictionary, variable: tuple[int, ...] = ()) -> dict[int, list[int]]:
    """Every object's sub-indices (`variable` for a VAR: canopen-monitor gives none, Lely sub-index 0)."""
    return {i: sorted(od[i].subindices) if hasattr(od[i], "subindices") else list(variable) for i in od}


def test_the_eds_files_load_in_python_canopen_and_canopen_monitor(tools: Path, eds_files: dict[str, Path]) -> None:
    res = subprocess.run(
        [str(tools), "-c", CANOPEN_MONITOR, *map(str, eds_files.values())], capture_output=True, text=True
    )
    assert res.returncode == 0, f"canopen-monitor refused one of {list(eds_files)}:\n{res.stderr[-2000:]}"
    seen = json.loads(res.stdout)
    for what, path in eds_files.items():
        od = _canopen(path)
        mon = {int(i): v for i, v in seen[str(path)].items()}
        assert {i: v[0] for i, v in mon.items()} == _objects(od), f"{what}: canopen-monitor's objects differ"
        for i in od:
            obj = od[i]
            types = {s: v.data_type for s, v in obj.subindices.items()} if hasattr(obj, "subindices") else None
            got = {int(s): t for s, t in mon[i][2].items()} if types is not None else mon[i][1]
            assert got == (types if types is not None else obj.data_type), f"{what} 0x{i:04X}: data types differ"
    law = (eds_files["user law"]).read_text()
    mine = "; my law, written by hand\n; another comment style\n; the record\n"  # comments under their header
    assert f"[2400]\n; law folder my_law: complex_vector_pi\n{mine}ParameterName=" in law
    assert "\n[2400sub1]\n; the bandwidth, above its section\nParameterName=bandwidth_Hz\n" in law
    assert "Kp is 2 pi f_bw L_hat" in law and "Ts is at least 1" in law  # a '=' of prose spelled out


def _lely_way(path: Path, out: Path) -> Path:
    """The EDS as a Lely user imports it: REAL32/REAL64 values as their bit pattern, the bench's own keys and
    [EmergencyCodes] left out."""
    raw = configparser.RawConfigParser()
    raw.optionxform = str  # type: ignore[assignment,method-assign]
    raw.read(path)
    lely = configparser.RawConfigParser()
    lely.optionxform = str  # type: ignore[assignment,method-assign]
    for sec in raw.sections():
        if sec == "EmergencyCodes":
            continue
        lely.add_section(sec)
        obj = INDEX.match(sec) is not None
        real = REAL.get(int(raw.get(sec, "DataType", fallback="0"), 0))
        for key, value in raw.items(sec):
            if obj and key.split(".")[0] in BENCH_KEYS:
                continue
            if real and key in ("DefaultValue", "LowLimit", "HighLimit") and value.strip():
                as_float, as_int, digits = real
                value = f"0x{struct.unpack(as_int, struct.pack(as_float, float(value)))[0]:0{digits}X}"
            lely.set(sec, key, value)
    with open(out, "w") as f:
        lely.write(f)
    return out


def _accepted(message: str, path: Path) -> bool:
    """A finding of Lely's checker on the EDS as written that is the bench's choice, not a fault: a key of the
    bench's own, its [EmergencyCodes], a decimal REAL32/REAL64 value."""
    if message == "unknown section in DCF: EmergencyCodes":
        return True
    m = re.fullmatch(r"invalid entry in \[(\w+)\]: ([\w.]+)", message)
    if m:
        return m.group(2).split(".")[0] in BENCH_KEYS
    m = re.fullmatch(r"invalid (DefaultValue|LowLimit|HighLimit) in \[(\w+)\]: (.*)", message)
    if m:
        raw = configparser.RawConfigParser()
        raw.read(path)
        try:
            float(m.group(3))  # a decimal number, as CiA 306 readers take it
        except ValueError:
            return False
        return int(raw.get(m.group(2), "DataType"), 0) in REAL
    return False


def test_the_eds_files_load_in_lelys_dcf_tools(tools: Path, eds_files: dict[str, Path], tmp_path: Path) -> None:
    for what, path in eds_files.items():
        lely = _lely_way(path, tmp_path / f"{what.replace(' ', '_')}.eds")
        res = subprocess.run([str(tools), "-c", LELY, str(path), str(lely)], capture_output=True, text=True)
        assert res.returncode == 0, f"{what}: Lely's dcf-tools refused it:\n{res.stderr[-2000:]}"
        got = json.loads(res.stdout)
        faults = [m for m in got["found"] if not _accepted(m, path)]
        assert not faults, f"{what}: Lely's checker: {faults[:5]}"
        assert got["found"], f"{what}: Lely found nothing to say of the bench's keys (did the check run?)"
        assert got["clean"] and not got["again"], f"{what}, imported Lely's way: {got['again'][:5]}"
        od = _canopen(path, got["node_id"])
        assert {int(i): v for i, v in got["objects"].items()} == _objects(od, (0,)), f"{what}: Lely's objects"
        for name, (cob_id, mapping) in got["pdos"].items():
            comm, maps = (0x1400, 0x1600) if name.startswith("rpdo") else (0x1800, 0x1A00)
            n = int(name[4:]) - 1
            assert cob_id == od[comm + n][1].default, f"{what} {name}: COB-ID"
            table = od[maps + n]
            want = [[v >> 16, (v >> 8) & 0xFF] for v in (table[s].default for s in range(1, table[0].default + 1)) if v]
            assert mapping == want, f"{what} {name}: mapping"
