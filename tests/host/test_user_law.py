"""A law from the user's own folder (issue 26): protocols/gen_od.py --law (its refusals, its merge),
`make LAW=DIR` and `bench ... --law DIR` (docs/ARCHITECTURE.md, "A law from your own folder")."""

from __future__ import annotations

import configparser
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from bench_cli import bench_cli
from law_util import rename

REPO = Path(__file__).resolve().parents[2]
FIXTURE = REPO / "tests" / "laws" / "zero_law"
SCENARIO = REPO / "tests" / "laws" / "zero_law.toml"
BUILD_TIMEOUT_S = 1800  # `bench run --law` builds the law first


def _gen_od():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("gen_od_user_law", REPO / "protocols" / "gen_od.py")
    assert spec is not None and spec.loader is not None
    mod = sys.modules.get(spec.name) or importlib.util.module_from_spec(spec)
    if spec.name not in sys.modules:
        sys.modules[spec.name] = mod  # its dataclasses look their module up
        spec.loader.exec_module(mod)
    return mod


def _law_copy(tmp_path: Path, name: str = "zero_law") -> Path:
    law = tmp_path / "user" / name  # a folder outside the repository
    shutil.copytree(FIXTURE, law)
    return law


def _edit(law: Path, old: str, new: str, count: int = 1) -> None:
    frag = law / "law.eds"
    text = frag.read_text()
    assert text.count(old) >= 1, old
    frag.write_text(text.replace(old, new, count))


# (what the edit does, old, new, count, what the refusal says, the section it names)
REFUSALS = [
    ("index outside the user range", "[2400", "[2600", -1, "outside 0x2400..0x24FF", "2600"),
    ("index used by drive.eds", "[2400", "[2203", -1, "already used in drive.eds", "2203"),
    ("index of a paper's law", "[2400", "[2501", -1, "already used in drive.eds (by the law folder yao2020)", "2501"),
    ("a paper's law's name", "CurrentLaws=zero_law", "CurrentLaws=pi", 1, "already a value of Controller", "2400"),
    ("a law named twice", "CurrentLaws=zero_law", "CurrentLaws=zero_law,zero_law", 1, "named twice", "2400"),
    (
        "two records",
        "[2400]",
        "[2401]\nParameterName=Other\nObjectType=0x9\nSubNumber=1\n\n[2400]",
        1,
        "more than one object",
        "2400",
    ),
    ("law name not a C identifier", "CurrentLaws=zero_law", "CurrentLaws=Zero-Law", 1, "not a lower-case C", "2400"),
    (
        "DataType by name",
        "DataType=0x0008",
        "DataType=REAL32",
        1,
        "DataType=REAL32: not a number as CiA 306",
        "2400sub1",
    ),
    ("law name of a built-in law", "CurrentLaws=zero_law", "CurrentLaws=pi", 1, "already a value", "2400"),
    ("no CurrentLaws key", "CurrentLaws=zero_law\n", "", 1, "no CurrentLaws", "2400"),
    ("a record named like a drive object", "ParameterName=Zero law", "ParameterName=Controller", 1, "[2200]", "2400"),
    (
        "a parameter named like the drive's",
        "ParameterName=gain\n",
        "ParameterName=Vmax_V\n",
        1,
        "drive's own",
        "2400sub1",
    ),
    (
        "an enum named like the drive's",
        "ParameterName=hold_periods\n",
        "ParameterName=reason\nValueNames=a,b\n",
        1,
        "enum OD_DRIVE_REASON_*",
        "2400sub2",
    ),
    ("unsupported data type", "DataType=0x0006", "DataType=0x0009", 1, "DataType 0x0009 not supported", "2400sub2"),
    ("a default that is not a number", "DefaultValue=0.5", "DefaultValue=half", 1, "not a number", "2400sub1"),
    ("a default out of its range", "DefaultValue=0.5", "DefaultValue=2", 1, "outside LowLimit..HighLimit", "2400sub1"),
    # a '=' in a value that is not prose: the EDS the bench writes must load in canopen-monitor (issue 52)
    ("a '=' in a value", "ParameterName=gain\n", "ParameterName=gain\nUnit=V=A\n", 1, "a '=' in the value", "2400sub1"),
    (
        "a sub-entry canopen refuses",
        "PDOMapping=0\nDescription=a parameter the law does not",
        "PDOMapping=x\nDescription=a parameter the law does not",
        1,
        "canopen refused",
        "2400sub2",
    ),
]


@pytest.mark.parametrize("what,old,new,count,says,section", REFUSALS, ids=[r[0] for r in REFUSALS])
def test_gen_refuses_a_bad_fragment_in_one_line_and_writes_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    what: str,
    old: str,
    new: str,
    count: int,
    says: str,
    section: str,
) -> None:
    law = _law_copy(tmp_path)
    _edit(law, old, new, count)
    out = tmp_path / "out"
    rc = _gen_od().main(["--law", str(law), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2, (what, err)
    assert len(err.strip().splitlines()) == 1, err
    assert str(law / "law.eds") in err and f"[{section}]" in err and says in err, err
    assert not out.exists()


def test_gen_merges_the_law_into_the_drive_eds_and_its_registry(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _gen_od().main(["--law", str(FIXTURE), "--out", str(out)]) == 0
    # the drive as built (protocols/generated/eds: drive.eds with the papers' law folders) and the user's law after it
    plain = configparser.ConfigParser(strict=False, interpolation=None)
    plain.read(REPO / "protocols" / "generated" / "eds" / "drive.eds")
    merged = configparser.ConfigParser(strict=False, interpolation=None)
    merged.read(out / "eds" / "drive.eds")
    names = plain.get("2200sub1", "valuenames").split(",")
    assert {"pi", "deadbeat_you2019", "dpcc_yao2020", "incremental_zhao2022"} <= set(names)
    assert merged.get("2200sub1", "valuenames").split(",") == [*names, "zero_law"]
    assert int(merged.get("2200sub1", "highlimit")) == len(names)
    assert merged.get("2200sub1", "defaultvalue") == plain.get("2200sub1", "defaultvalue")  # its DefaultLaw
    count = int(plain.get("ManufacturerObjects", "supportedobjects"))
    assert int(merged.get("ManufacturerObjects", "supportedobjects")) == count + 1
    assert int(merged.get("ManufacturerObjects", str(count + 1)), 0) == 0x2400
    assert (out / "eds" / "plant.eds").read_text() == (REPO / "protocols" / "eds" / "plant.eds").read_text()
    table = (out / "generated" / "current_law_table.c").read_text()
    row = re.search(r"\{(\d+)u, &current_law_zero_law, 0x2400u,", table)
    assert row is not None and int(row.group(1)) == len(names)
    assert "od_drive_zero_law_t" in (out / "generated" / "od_drive_fields.h").read_text()
    # the plain drive's generated files are not touched, and --law needs --out
    assert _gen_od().main(["--check"]) == 0
    assert _gen_od().main(["--law", str(FIXTURE)]) == 2


def _listing(folder: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(folder)): (p.stat().st_mtime_ns, p.stat().st_size) for p in folder.rglob("*")}


_rename = rename  # the fixture as a law of another name (tests/host/law_util.py)


def test_make_law_builds_every_drive_target_from_a_folder_outside_the_repo(tmp_path: Path) -> None:
    law = _law_copy(tmp_path, "copied_law")
    _rename(law, "copied_law")
    before = _listing(law)
    from bench.law import build_folder

    build = build_folder(law, "copied_law")  # the folder `bench run --law` uses too (test_law_folders.py)
    proc = subprocess.run(["make", "-C", str(REPO), f"LAW={law}", "-j2"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    targets = ["bin/drive_node", "bin/plant_node", "bin/fault_gateway", "libhil.so", "eds/drive.eds"]
    if shutil.which("arm-none-eabi-gcc"):
        targets.append("mcu/drive_mcu.elf")
    assert [t for t in targets if not (build / t).is_file()] == []
    assert (
        "current_law_copied_law"
        in subprocess.run(["nm", str(build / "libhil.so")], capture_output=True, text=True).stdout
    )
    assert _listing(law) == before  # nothing written in the user's folder


def test_bench_names_the_users_file_when_the_law_does_not_compile(tmp_path: Path) -> None:
    law = _law_copy(tmp_path, "broken_law")
    _rename(law, "broken_law")
    src = law / "zero_law.c"
    src.write_text(src.read_text().replace("->steps++;", "->steps++ not_c;"))
    proc = bench_cli(
        "run", SCENARIO, "--law", law, "--bus", "direct", "--out", tmp_path / "run", timeout=BUILD_TIMEOUT_S, expect=2
    )
    assert f"{src}:" in proc.stderr and "error:" in proc.stderr, proc.stderr
    assert not (tmp_path / "run").exists()


def test_bench_says_which_symbol_the_folder_must_define(tmp_path: Path) -> None:
    law = _law_copy(tmp_path, "nameless_law")
    _rename(law, "nameless_law")
    src = law / "zero_law.c"
    src.write_text(src.read_text().replace("const current_law_t current_law_nameless_law", "const current_law_t other"))
    proc = bench_cli(
        "run", SCENARIO, "--law", law, "--bus", "direct", "--out", tmp_path / "run", timeout=BUILD_TIMEOUT_S, expect=2
    )
    assert "current_law_nameless_law" in proc.stderr.splitlines()[-1], proc.stderr


def test_a_descriptor_without_step_is_refused_when_built(tmp_path: Path) -> None:
    """The drive calls step every period: a NULL there is refused by the build (law_check.c), not a crash."""
    law = _law_copy(tmp_path, "stepless_law")
    _rename(law, "stepless_law")
    src = law / "zero_law.c"
    src.write_text(
        src.read_text().replace(".step = zero_step,", ".step = 0,").replace("static void zero_step", "void zero_step")
    )
    proc = bench_cli(
        "run", SCENARIO, "--law", law, "--bus", "direct", "--out", tmp_path / "run", timeout=BUILD_TIMEOUT_S, expect=2
    )
    assert "current_law_stepless_law.step is NULL" in proc.stderr.splitlines()[-1], proc.stderr
    assert not (tmp_path / "run").exists()


def test_a_law_whose_command_is_not_finite_ends_the_run_law_fault(tmp_path: Path) -> None:
    """A NaN command: the drive commands 0 V in its safe state (EMCY 0xFF06), one command frame a period (no
    interference), and the run's status is law_fault (exit 10)."""
    import numpy as np

    law = _law_copy(tmp_path, "nan_law")
    _rename(law, "nan_law")
    src = law / "zero_law.c"
    text = src.read_text().replace(
        "*out = (current_law_out_t){0};",
        "*out = (current_law_out_t){0};\n    if (in->iq_ref_A > 0.5f) out->v_alpha_V = NAN;",
    )
    src.write_text(text.replace("    (void)in;\n", ""))
    out = tmp_path / "run"
    proc = bench_cli(
        "run", SCENARIO, "--law", law, "--set", "controller.controller=nan_law", "--bus", "direct",
        "--no-viewer", "--out", out, timeout=BUILD_TIMEOUT_S, expect=10,
    )  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "law_fault" and summary["bus_stats"]["interference"]["frames"] == 0, summary["status"]
    faults = [e for e in summary["emcy"] if e["node"] == "drive" and e["code"] == "0xFF06"]
    assert [e["period"] for e in faults] == [10], summary["emcy"]  # the reference step's period (the scenario)
    assert "refused its current law nan_law at period 10" in proc.stdout
    tr = np.load(out / "traces.npy")
    assert np.all(tr["v_alpha_V"][np.isfinite(tr["v_alpha_V"])] == 0.0)


def test_a_run_that_never_selects_the_law_is_refused(tmp_path: Path) -> None:
    scenario = REPO / "scenarios" / "you2019_step.toml"
    args = ["run", str(scenario), "--law", str(FIXTURE), "--bus", "direct", "--out", str(tmp_path / "run")]
    proc = bench_cli(*args, timeout=BUILD_TIMEOUT_S, expect=2)
    assert "does not select the law zero_law" in proc.stderr and "controller.controller=zero_law" in proc.stderr
    assert not (tmp_path / "run").exists()


def test_bench_run_selects_the_users_law(tmp_path: Path) -> None:
    """End to end: the law's build runs, the drive runs the law (0 V: no current), its record is the
    scenario's (gain) and its status reaches the trace (steps)."""
    import numpy as np

    out = tmp_path / "run"
    args = ["run", str(SCENARIO), "--law", str(FIXTURE), "--bus", "direct", "--out", str(out), "--no-viewer"]
    bench_cli(*args, timeout=BUILD_TIMEOUT_S, expect=0)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["identified"]["controller"] == "zero_law", summary["identified"]
    assert summary["status"] == "ok"
    tr = np.load(out / "traces.npy")
    steps = tr["Zero_law_steps"][np.isfinite(tr["Zero_law_steps"])]
    assert len(steps) > 10 and np.all(np.diff(steps) > 0), steps
    assert np.all(tr["Zero_law_gain_seen"][np.isfinite(tr["Zero_law_gain_seen"])] == np.float32(0.25))
    assert np.nanmax(np.abs(tr["v_alpha_V"])) == 0.0 and np.nanmax(np.abs(tr["v_beta_V"])) == 0.0


SCENARIO_PROBE = """
import json, sys
from bench.scenario import load
sc = load(__import__("pathlib").Path(sys.argv[1]), [])
print(json.dumps([[s.key, s.param.obj, s.param.index, s.value] for s in sc.settings if s.param is not None]))
"""


def test_scenario_selects_the_law_and_sets_its_record_by_name_in_the_laws_build(tmp_path: Path) -> None:
    """BENCH_BUILD_DIR (what --law sets) brings the merged EDS: the law's value and its record's entries."""
    out = tmp_path / "out"
    assert _gen_od().main(["--law", str(FIXTURE), "--out", str(out)]) == 0
    env = {**os.environ, "BENCH_BUILD_DIR": str(out)}
    proc = subprocess.run(
        [sys.executable, "-c", SCENARIO_PROBE, str(SCENARIO)], capture_output=True, text=True, cwd=REPO, env=env
    )
    assert proc.returncode == 0, proc.stderr
    settings = {key: (obj, index, value) for key, obj, index, value in json.loads(proc.stdout)}
    names = configparser.ConfigParser(strict=False, interpolation=None)
    names.read(out / "eds" / "drive.eds")
    assert settings["controller.controller"][2] == names.get("2200sub1", "valuenames").split(",").index("zero_law")
    assert settings["controller.gain"] == ("Zero law", 0x2400, 0.25)
    # without the law's build, the plain drive has no such law
    plain = {k: v for k, v in env.items() if k != "BENCH_BUILD_DIR"}
    proc = subprocess.run(
        [sys.executable, "-c", SCENARIO_PROBE, str(SCENARIO)], capture_output=True, text=True, cwd=REPO, env=plain
    )
    assert proc.returncode != 0 and "zero_law" in proc.stderr
