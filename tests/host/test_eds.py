"""The EDS files are the single source of truth: they load in `canopen` without a
warning, and the generated C object dictionaries are not stale."""

from __future__ import annotations

import ast
import logging
import re
import shutil
import subprocess
import sys
from pathlib import Path

import canopen
import pytest

from bench.paths import EDS_DIR, REPO


@pytest.mark.parametrize("node", ["plant", "drive"])
def test_eds_loads_in_canopen_without_warnings(node: str, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING):
        od = canopen.import_od(str(EDS_DIR / f"{node}.eds"), node_id=1)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
    for index in (
        0x1000,
        0x1001,
        0x1003,
        0x1005,
        0x1008,
        0x1014,
        0x1016,
        0x1017,
        0x1018,
        0x1019,
        0x1400,
        0x1600,
        0x1800,
        0x1A00,
    ):
        assert index in od, f"{node}.eds lacks 0x{index:04X}"
    assert od.device_information.product_name


def test_generated_object_dictionaries_are_current() -> None:
    res = subprocess.run(
        [sys.executable, str(REPO / "protocols" / "gen_od.py"), "--check"], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr


def test_generator_stands_on_its_own() -> None:
    """protocols/gen_od.py needs `canopen` only: it runs with the bench made unimportable."""
    code = (
        "import runpy, sys; sys.modules['bench'] = None; sys.argv = ['gen_od.py', '--check']; "
        f"runpy.run_path({str(REPO / 'protocols' / 'gen_od.py')!r}, run_name='__main__')"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr


def _gen_od():  # type: ignore[no-untyped-def]
    import importlib.util

    if "gen_od" in sys.modules:
        return sys.modules["gen_od"]
    spec = importlib.util.spec_from_file_location("gen_od", REPO / "protocols" / "gen_od.py")
    assert spec is not None and spec.loader is not None
    gen = importlib.util.module_from_spec(spec)
    sys.modules["gen_od"] = gen  # its dataclasses look their module up
    spec.loader.exec_module(gen)
    return gen


# What only the EDS reader (protocols/eds_reader.py) does: make an INI parser, call canopen's EDS import.
PARSING_CALLS = {"ConfigParser", "RawConfigParser", "import_od", "import_eds"}


def own_eds_parsing(source: str) -> list[str]:
    """Calls of a module that parse an EDS itself instead of through the reader (`reader.` / `eds_reader.`)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
        via = func.value.id if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) else ""
        if name in PARSING_CALLS and via not in ("reader", "eds_reader"):
            out.append(f"line {node.lineno}: {ast.unparse(func)}(...)")
    return out


def test_one_eds_reader_for_the_generator_and_the_bench() -> None:
    """protocols/gen_od.py and bench/eds.py read the EDS files through one module, protocols/eds_reader.py (it used
    to be two copies of the same helpers, checked against each other)."""
    import bench.eds

    gen = _gen_od()
    assert Path(gen.eds_reader.__file__).resolve() == REPO / "protocols" / "eds_reader.py"
    assert bench.eds.reader is gen.eds_reader  # one module object, whichever was imported first
    for path in (REPO / "protocols" / "gen_od.py", REPO / "bench" / "eds.py"):
        assert own_eds_parsing(path.read_text()) == [], path
    assert own_eds_parsing("import configparser\nraw = configparser.ConfigParser()\nod = canopen.import_od(p)\n") == [
        "line 2: configparser.ConfigParser(...)",
        "line 3: canopen.import_od(...)",
    ]  # the check bites
    reader_source = (REPO / "protocols" / "eds_reader.py").read_text()
    imported = {
        (n.module if isinstance(n, ast.ImportFrom) else a.name).split(".")[0]
        for n in ast.walk(ast.parse(reader_source))
        if isinstance(n, (ast.Import, ast.ImportFrom))
        for a in n.names
    }
    assert imported - sys.stdlib_module_names - {"__future__"} == {"canopen"}, imported  # gen_od needs only canopen


@pytest.mark.parametrize("node", ["plant", "drive"])
def test_value_names_cover_the_entry_range(node: str) -> None:
    from bench.eds import float_limits, value_names

    path = EDS_DIR / f"{node}.eds"
    od = canopen.import_od(str(path))
    n = names = 0
    for obj in od.values():
        for var in [obj] if isinstance(obj, canopen.objectdictionary.ODVariable) else obj.values():
            if var.data_type == canopen.objectdictionary.datatypes.REAL32:
                lo, hi = float_limits(path, var)
                assert (lo is None) == (hi is None) and (lo is None or lo <= hi), var.name
                n += 1
            if value_names(path, var):
                names += 1
                assert var.max is not None and len(value_names(path, var)) == var.max + 1, var.name  # HighLimit
    assert n > 10 and names >= 2


# ------------------------------------------------------------------ EMCY codes and the injector's size
EMCY_MACRO = re.compile(r"\b(CO|PLANT|DRIVE)_EMCY_([A-Z0-9_]+)\b")
EMCY_DEFINE = re.compile(r"^\s*#\s*define\s+((?:CO|PLANT|DRIVE)_EMCY_\w+)\s*(.*)$", re.M)
SOURCE_OF_PREFIX = {"CO": "common", "PLANT": "plant", "DRIVE": "drive"}
HAND_WRITTEN_C = ("protocols", "plant_rt", "firmware_shim", "bench/direct", "tests/c")
INC = [
    f"-I{REPO / d}"
    for d in (
        "protocols/canopen",
        "protocols/generated",
        "protocols/faults",
        "plant_rt/blocks",
        "plant_rt/models",
        "plant_rt/core",
        "plant_rt/node",
        "firmware_shim/core",
        "firmware_shim/shim",
        *(str(d.relative_to(REPO)) for d in sorted((REPO / "firmware_shim" / "laws").iterdir())),
    )
]


def _code(text: str) -> str:
    """C without its comments (which name codes in words: 'EMCY 0xFF01')."""
    return re.sub(r"/\*.*?\*/|//[^\n]*", " ", text, flags=re.S)


def _hand_written_c() -> list[Path]:
    return sorted(
        p for d in HAND_WRITTEN_C for p in (REPO / d).rglob("*.[ch]") if "generated" not in p.relative_to(REPO).parts
    )


def emcy_violations(files: dict[str, str], eds_names: dict[str, set[str]]) -> list[str]:
    """An EMCY code written by hand in C (a #define of a code: a second place), or an EMCY macro the C uses that the
    EDS does not declare (CO_ from common.ini, PLANT_/DRIVE_ from the node's [EmergencyCodes])."""
    bad, other = [], set()
    for name, text in files.items():
        for macro, value in EMCY_DEFINE.findall(text):
            if re.match(r"0x[0-9A-Fa-f]{4}u?\b", value.strip()):
                bad.append(f"{name}: #define {macro} {value.strip()} (declare it in the EDS's [EmergencyCodes])")
            other.add(macro)
    for name, text in files.items():
        for prefix, rest in EMCY_MACRO.findall(text):
            macro = f"{prefix}_EMCY_{rest}"
            if rest.lower() not in eds_names[SOURCE_OF_PREFIX[prefix]] and macro not in other:
                bad.append(f"{name}: {macro} is no EMCY code of the EDS")
    return sorted(set(bad))


def test_every_emcy_code_the_c_sends_is_named_in_the_eds() -> None:
    from bench.eds import emcy_table

    names = {source: {c.name for c in codes} for source, codes in emcy_table().items()}
    files = {str(p.relative_to(REPO)): _code(p.read_text()) for p in _hand_written_c()}
    assert any("PLANT_EMCY_OVERCURRENT" in t for t in files.values()) and len(files) > 50
    assert emcy_violations(files, names) == []
    # the check bites: a code written by hand, a macro the EDS does not declare
    assert emcy_violations({"x.h": "#define DRIVE_EMCY_NEW 0xFF42u\n"}, names) == [
        "x.h: #define DRIVE_EMCY_NEW 0xFF42u (declare it in the EDS's [EmergencyCodes])"
    ]
    assert emcy_violations({"x.c": "co_emcy_raise(n, PLANT_EMCY_MEAS_LOST, 0, m);"}, names) == [
        "x.c: PLANT_EMCY_MEAS_LOST is no EMCY code of the EDS"
    ]
    # and no hex code handed straight to an EMCY function outside the tests
    literal = re.compile(r"\b\w*emcy\w*\s*\([^;]*?\b0x[0-9A-Fa-f]{4}u?\b", re.I)
    sent = [f"{n}: {m.group(0)}" for n, t in files.items() if "/tests/" not in f"/{n}" for m in literal.finditer(t)]
    assert sent == []
    assert literal.search("co_emcy_raise(node, 0xFF10u, 0, msef);")  # the check bites


def _static_asserts(tmp_path: Path, header: str, checks: dict[str, int]) -> subprocess.CompletedProcess[str]:
    src = tmp_path / f"check_{Path(header).stem}.c"
    src.write_text(
        f'#include "{header}"\n'
        + "".join(f'_Static_assert({m} == {v}u, "{m} != {v:#06x} of the EDS");\n' for m, v in checks.items())
    )
    cc = shutil.which("cc") or shutil.which("gcc")
    assert cc, "no C compiler"
    cmd = [cc, "-std=c11", "-Wall", "-Wextra", "-Werror", "-fsyntax-only", *INC, str(src)]
    return subprocess.run(cmd, capture_output=True, text=True)


def test_the_c_sees_the_eds_values(tmp_path: Path) -> None:
    """Through the headers the C includes (co_emcy.h, plant_app.h, drive_app.h, fault_injector.h), every EMCY macro
    equals its code in the EDS and FI_MAX_RULES the MaxRules the bench checks a scenario's [[faults]] against."""
    from bench.eds import emcy_table
    from bench.emcy import emcy_names
    from bench.scenario.faults import max_rules

    table = emcy_table()
    headers = {"common": "co_emcy.h", "plant": "plant_app.h", "drive": "drive_app.h"}
    for source, header in headers.items():
        prefix = next(p for p, s in SOURCE_OF_PREFIX.items() if s == source)
        checks = {f"{prefix}_EMCY_{c.name.upper()}": c.code for c in table[source]}
        assert checks, source
        res = _static_asserts(tmp_path, header, checks)
        assert res.returncode == 0, res.stderr
    assert max_rules() > 0  # MaxRules in protocols/eds/common.ini
    res = _static_asserts(tmp_path, "fault_injector.h", {"FI_MAX_RULES": max_rules()})
    assert res.returncode == 0, res.stderr
    rule_table = {"sizeof(((fi_t *)0)->rule) / sizeof(fi_rule_t)": max_rules()}
    assert _static_asserts(tmp_path, "fault_injector.h", rule_table).returncode == 0
    # the check bites
    assert _static_asserts(tmp_path, "co_emcy.h", {"CO_EMCY_HEARTBEAT": 0x8131}).returncode != 0
    # the bench's names are the EDS's, one code one name
    assert emcy_names() == {c.code: c.name for codes in table.values() for c in codes}
    assert emcy_names()[0x8130] == "heartbeat" and emcy_names()[0xFF10] == "drive_lost"


def _write_eds_dir(tmp_path: Path, common: str, plant: str) -> Path:
    d = tmp_path / "eds"
    d.mkdir(exist_ok=True)
    (d / "common.ini").write_text(f"[EmergencyCodes]\n{common}\n[FaultInjector]\nMaxRules=4\n")
    (d / "plant.eds").write_text(f"[EmergencyCodes]\n{plant}\n")
    return d


@pytest.mark.parametrize(
    ("common", "plant", "says"),
    [
        ("heartbeat=0x8130", "overcurrent=0x2310", ""),
        ("heartbeat=0x8130", "Overcurrent=0x2310", "lower-case C identifier"),
        ("heartbeat=0x8130", "overcurrent=0x231", "four hex digits"),
        ("heartbeat=0x8130", "overcurrent=0x2310\ntrip=0x2310", "code 0x2310 named twice"),
        ("heartbeat=0x8130", "overcurrent=0x2310\novercurrent=0x2311", "option 'overcurrent'"),
        ("heartbeat=0x8130", "lost=0x8130", "code 0x8130 is declared in"),
        ("heartbeat=0x8130", "heartbeat=0xFF10", "name heartbeat is declared in"),
        ("heartbeat=0x8130 a */ comment", "overcurrent=0x2310", "'*/' in the description"),
    ],
)
def test_the_reader_refuses_an_emcy_code_declared_badly(tmp_path: Path, common: str, plant: str, says: str) -> None:
    import bench.eds

    d = _write_eds_dir(tmp_path, common, plant)
    if not says:
        table = bench.eds.reader.emcy_table(d, ("plant",))
        assert [(c.name, c.code) for c in table["common"] + table["plant"]] == [
            ("heartbeat", 0x8130),
            ("overcurrent", 0x2310),
        ]
        assert bench.eds.reader.fault_injector(bench.eds.reader.parse(d / "common.ini"), "c") == {"MaxRules": 4}
        return
    with pytest.raises(ValueError, match=re.escape(says)):
        bench.eds.reader.emcy_table(d, ("plant",))


def test_a_law_build_carries_the_shared_file(tmp_path: Path) -> None:
    """gen_od.py --law writes common.ini beside the merged EDS files (the bench reads EMCY names and the injector's
    size from BENCH_BUILD_DIR/eds) and eds_common.h with the other generated files."""
    out = tmp_path / "out"
    assert _gen_od().main(["--law", str(REPO / "tests" / "laws" / "zero_law"), "--out", str(out)]) == 0
    assert (out / "eds" / "common.ini").read_text() == (EDS_DIR / "common.ini").read_text()
    assert (out / "generated" / "eds_common.h").read_text() == (
        REPO / "protocols" / "generated" / "eds_common.h"
    ).read_text()
    emcy = [
        ln for ln in (REPO / "protocols" / "generated" / "od_drive_fields.h").read_text().splitlines() if "_EMCY_" in ln
    ]
    merged = (out / "generated" / "od_drive_fields.h").read_text().splitlines()
    assert len(emcy) > 1 and [ln for ln in merged if "_EMCY_" in ln] == emcy  # the drive's codes, kept in the merge


def test_generator_detects_a_stale_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """--check must fail when a generated file differs (the test above could not fail otherwise). On a copy
    generated with --out: an edit of the repository's own file raced the test above in another xdist worker."""
    gen_od = str(REPO / "protocols" / "gen_od.py")
    subprocess.run([sys.executable, gen_od, "--out", str(tmp_path)], capture_output=True, check=True)
    check = [sys.executable, gen_od, "--check", "--out", str(tmp_path)]
    assert subprocess.run(check, capture_output=True, text=True).returncode == 0
    gen = tmp_path / "generated" / "od_drive.c"
    gen.write_text(gen.read_text() + "/* edited by hand */\n")
    res = subprocess.run(check, capture_output=True, text=True)
    assert res.returncode == 1 and "stale" in res.stderr and str(gen) in res.stderr


def test_controller_status_values_are_pdo_mappable() -> None:
    """Every read-only status/estimate value of the controller objects can be traced per period (a scenario's
    [trace] maps it into TPDO3/4); parameters (rw) stay SDO-only where the EDS says so."""
    od = canopen.import_od(str(EDS_DIR / "drive.eds"), node_id=0x20)
    for obj in ("Online tuning", "Yao 2020 DPCC", "Zhao 2022", "Drive status"):
        for var in od[obj].values():
            if var.subindex > 0 and var.access_type == "ro":
                assert var.pdo_mappable and var.readable, f"{obj}.{var.name} is read-only but not PDO-mappable"
    for sub in ("K1_V_A", "K2_V_A", "G_V_A", "limited"):
        assert od["Zhao 2022"][sub].pdo_mappable, sub
    assert not od["Controller"]["Ts_s"].pdo_mappable  # a parameter, refused by the node (0x06040041)


@pytest.mark.parametrize("node", ["plant", "drive"])
def test_cia301_details(node: str) -> None:
    """Found by canopend and canopen-monitor: the nodes answer no RTR, so every TPDO's default COB-ID
    says so (bit 30 set, CiA 301 7.5.2.35); and no Description carries '=', which INI readers split on."""
    od = canopen.import_od(str(EDS_DIR / f"{node}.eds"), node_id=0x10)
    tpdos = [od[0x1800 + n][1] for n in range(512) if 0x1800 + n in od]
    assert tpdos
    for var in tpdos:
        assert var.default & 0x40000000, f"{node}.eds {var.index:04X}sub1 = {var.default:#x}: RTR allowed"
    text = (EDS_DIR / f"{node}.eds").read_text()
    bad = [ln for ln in text.splitlines() if ln.startswith("Description=") and "=" in ln[len("Description=") :]]
    assert not bad, bad[:3]


def test_an_emcy_name_no_eds_declares_is_refused() -> None:
    """A renamed [EmergencyCodes] key must not quietly turn off what its code judges (the status law_fault)."""
    from bench.emcy import emcy_codes

    assert emcy_codes("safe_overrun", "heartbeat") == [0xFF07, 0x8130]
    with pytest.raises(KeyError, match="safe_overrun_renamed"):
        emcy_codes("heartbeat", "safe_overrun_renamed")


# ------------------------------------------------------------------ named bits (BitNames): Measurement.status
STATUS = ("plant", "Measurement", "status")  # plant.eds 0x2100:05, BitNames=trip,holding,missed,held
BIT_DEFINE = re.compile(r"^\s*#\s*define\s+(PLANT_STATUS_\w+)\s+0x([0-9A-Fa-f]+)u?\b", re.M)


def bit_mismatches(header: str, masks: dict[str, int]) -> list[str]:
    """A generated header's PLANT_STATUS_* #defines against the EDS's masks: one missing, one extra, one different."""
    defined = {m: int(v, 16) for m, v in BIT_DEFINE.findall(header)}
    want = {f"PLANT_STATUS_{n.upper()}": m for n, m in masks.items()}
    return sorted(
        f"{k}: C {defined.get(k)}, EDS {want.get(k)}"
        for k in defined.keys() | want.keys()
        if defined.get(k) != want.get(k)
    )


def python_mask_mismatches(masks: dict[str, int]) -> list[str]:
    """The masks of Measurement.status the bench's Python uses, each against the EDS's mask of its bit."""
    from bench.faults import measure
    from bench.run.decode import rows
    from bench.run.verdict import faults, watch

    used = {
        "rows.PLANT_STATUS_MISSED": (rows.PLANT_STATUS_MISSED, "missed"),
        "StatusWatch.BITS['tripped']": (faults.StatusWatch.BITS["tripped"], "trip"),
        "StatusWatch.BITS['missed']": (faults.StatusWatch.BITS["missed"], "missed"),
        "StatusWatch.BITS['held']": (faults.StatusWatch.BITS["held"], "held"),
        "measure.HELD": (measure.HELD, "held"),
        "watch.STATUS_TRIP": (watch.STATUS_TRIP, "trip"),
    }
    return [f"{k} = {v:#x}, EDS {bit} = {masks.get(bit)}" for k, (v, bit) in used.items() if masks.get(bit) != v]


def test_status_bits_are_the_eds_ones(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Measurement.status's bits are named once, by BitNames in plant.eds: the generated PLANT_STATUS_* the C sees
    through plant_app.h, and the masks of the bench's Python (bench.eds.bits), equal the EDS's; none is written by
    hand."""
    from bench.eds import bits
    from bench.run.decode import rows

    masks = bits(*STATUS)
    assert {"trip", "holding", "missed", "held"} <= masks.keys()
    assert all(m and m & (m - 1) == 0 for m in masks.values()) and len(set(masks.values())) == len(masks)
    header = (REPO / "protocols" / "generated" / "od_plant_fields.h").read_text()
    assert bit_mismatches(header, masks) == []
    checks = {f"PLANT_STATUS_{n.upper()}": m for n, m in masks.items()}
    res = _static_asserts(tmp_path, "plant_app.h", checks)
    assert res.returncode == 0, res.stderr
    hand = [
        f"{p.relative_to(REPO)}: #define {m}"
        for p in _hand_written_c()
        for m, _ in BIT_DEFINE.findall(_code(p.read_text()))
        if m in checks
    ]
    assert hand == []  # no second place in C
    assert python_mask_mismatches(masks) == []
    for module in ("run/decode/rows.py", "run/verdict/faults.py", "faults/measure.py", "run/verdict/watch.py"):
        assert 'bits("plant", "Measurement", "status")' in (REPO / "bench" / module).read_text(), module
    # the checks bite: a generated value that is not the EDS's, a bit missing, the C and the Python disagreeing
    assert bit_mismatches(header, {**masks, "held": 0x100}) == [f"PLANT_STATUS_HELD: C {masks['held']}, EDS 256"]
    assert bit_mismatches(header, {**masks, "lost": 0x100}) == ["PLANT_STATUS_LOST: C None, EDS 256"]
    assert _static_asserts(tmp_path, "plant_app.h", {**checks, "PLANT_STATUS_MISSED": 0x100}).returncode != 0
    monkeypatch.setattr(rows, "PLANT_STATUS_MISSED", 0x100)
    assert python_mask_mismatches(masks) == [f"rows.PLANT_STATUS_MISSED = 0x100, EDS missed = {masks['missed']}"]


def _plant_eds_with(tmp_path: Path, section: str, keys: str) -> Path:
    """plant.eds in tmp_path/eds with `keys` (lines) added to `section` (BitNames=... of 2100sub5 replaced)."""
    text = re.sub(r"^BitNames=.*\n", "", (EDS_DIR / "plant.eds").read_text(), flags=re.M)
    head = f"[{section}]\n"
    assert head in text
    d = tmp_path / "eds"
    d.mkdir(exist_ok=True)
    (d / "plant.eds").write_text(text.replace(head, head + keys + "\n", 1))
    return d


def test_the_generator_writes_the_bits_the_eds_names(tmp_path: Path) -> None:
    """Another BitNames gives other #defines: the C comes from the EDS (an unnamed bit, a fifth one)."""
    import bench.eds

    d = _plant_eds_with(tmp_path, "2100sub5", "BitNames=trip,,missed,held,lost")
    header = _gen_od().render("plant", d)["od_plant_fields.h"]
    var = bench.eds.load("plant")["Measurement"]["status"]
    names = bench.eds.reader.bit_names(bench.eds.reader.parse(d / "plant.eds"), var)
    assert names == ("trip", "", "missed", "held", "lost")
    masks = {n: 1 << i for i, n in enumerate(names) if n}
    assert bit_mismatches(header, masks) == []
    assert "#define PLANT_STATUS_LOST 0x10u" in header and "PLANT_STATUS_HOLDING" not in header
    assert bit_mismatches(header, bench.eds.bits(*STATUS)) != []  # not the repository's


@pytest.mark.parametrize(
    ("section", "keys", "says"),
    [
        ("2100sub5", "BitNames=trip,Holding", "lower-case C identifiers"),
        ("2100sub5", "BitNames=trip,trip", "lower-case C identifiers"),
        ("2100sub5", "BitNames=,", "lower-case C identifiers"),
        ("2100sub5", "BitNames=" + ",".join(f"b{i}" for i in range(9)), "9 bits, the entry has 8"),
        ("2100sub5", "BitNames=trip\nValueNames=a,b", "without ValueNames"),
        ("2100sub1", "BitNames=trip", "only an UNSIGNED8/16/32 entry"),  # i_a_A, a REAL32
    ],
)
def test_the_reader_refuses_bits_named_badly(tmp_path: Path, section: str, keys: str, says: str) -> None:
    d = _plant_eds_with(tmp_path, section, keys)
    gen = _gen_od()
    with pytest.raises(gen.EdsError, match=re.escape(says)):
        gen.render("plant", d)
