"""The EDS files are the single source of truth: they load in `canopen` without a
warning, and the generated C object dictionaries are not stale."""

from __future__ import annotations

import logging
import subprocess
import sys

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


@pytest.mark.parametrize("node", ["plant", "drive"])
def test_generator_and_bench_read_the_same_float_limits_and_value_names(node: str) -> None:
    import importlib.util

    from bench.eds import float_limits, value_names

    spec = importlib.util.spec_from_file_location("gen_od", REPO / "protocols" / "gen_od.py")
    assert spec is not None and spec.loader is not None
    gen = importlib.util.module_from_spec(spec)
    sys.modules["gen_od"] = gen  # its dataclasses look their module up
    spec.loader.exec_module(gen)
    path = EDS_DIR / f"{node}.eds"
    raw = gen._raw(path)
    od = canopen.import_od(str(path))
    n = names = 0
    for obj in od.values():
        for var in [obj] if isinstance(obj, canopen.objectdictionary.ODVariable) else obj.values():
            if var.data_type == canopen.objectdictionary.datatypes.REAL32:
                assert gen.float_limits(raw, var) == float_limits(path, var), var.name
                n += 1
            assert tuple(gen.value_names(raw, var)) == value_names(path, var), var.name
            if value_names(path, var):
                names += 1
                assert var.max is not None and len(value_names(path, var)) == var.max + 1, var.name  # HighLimit
    assert n > 10 and names >= 2


def test_generator_detects_a_stale_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """--check must fail when a generated file differs (the test above could not fail otherwise)."""
    import shutil

    gen = REPO / "protocols" / "generated" / "od_drive.c"
    backup = tmp_path / "od_drive.c"
    shutil.copy(gen, backup)
    try:
        gen.write_text(gen.read_text() + "/* edited by hand */\n")
        res = subprocess.run(
            [sys.executable, str(REPO / "protocols" / "gen_od.py"), "--check"], capture_output=True, text=True
        )
        assert res.returncode == 1 and "stale" in res.stderr
    finally:
        shutil.copy(backup, gen)


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
