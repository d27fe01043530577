"""The papers' current laws are law folders like a user's (issue 41): firmware_shim/laws/<paper>/ holds the
law's C files, headers and one law.eds record, merged into every drive by the generator that merges a user's
law (protocols/gen_law.py). A paper's folder and a user's differ only in where they live (and so in the index
range of their record); a fourth paper is one more folder."""

from __future__ import annotations

import configparser
import importlib.util
import re
import shutil
import sys
from pathlib import Path
from types import ModuleType

import pytest

from bench.paths import REPO

LAWS = REPO / "firmware_shim" / "laws"
CORE = REPO / "firmware_shim" / "core"
PLAIN_EDS = REPO / "protocols" / "eds" / "drive.eds"
BUILT_EDS = REPO / "protocols" / "generated" / "eds" / "drive.eds"


def _gen_law() -> ModuleType:
    sys.path.insert(0, str(REPO / "protocols"))
    try:
        spec = importlib.util.spec_from_file_location("gen_law_papers", REPO / "protocols" / "gen_law.py")
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    finally:
        sys.path.remove(str(REPO / "protocols"))


def _supported() -> set[int]:
    return {0x0001, 0x0002, 0x0003, 0x0004, 0x0005, 0x0006, 0x0007, 0x0008}


def _ini(text: str) -> configparser.ConfigParser:
    ini = configparser.ConfigParser(strict=False, interpolation=None)
    ini.optionxform = str  # type: ignore[assignment,method-assign]
    ini.read_string(text)
    return ini


def test_the_drive_eds_names_no_law_and_the_folders_name_them_all() -> None:
    """drive.eds holds the drive's own objects: open loop is its only law; the papers' records and laws come from
    their folders, in their records' index order, so the values of Controller.controller are as before."""
    plain, built = _ini(PLAIN_EDS.read_text()), _ini(BUILT_EDS.read_text())
    assert plain.get("2200sub1", "ValueNames") == "open_loop"
    assert not [s for s in plain.sections() if plain.has_option(s, "CurrentLaws")]
    names = built.get("2200sub1", "ValueNames").split(",")
    assert names == [
        "open_loop",
        "pi",
        "deadbeat_you2019",
        "dpcc_yao2020",
        "incremental_zhao2022",
        "predictive_zhao2022",
    ]
    assert names[int(built.get("2200sub1", "DefaultValue"))] == plain.get("2200sub1", "DefaultLaw")
    gen = _gen_law()
    records = [
        int(re.search(r"^\[([0-9A-Fa-f]{4})\]", (d / "law.eds").read_text(), re.M).group(1), 16)  # type: ignore[union-attr]
        for d in gen.bench_law_dirs()
    ]
    assert records == sorted(records) and all(r in gen.BENCH_LAWS for r in records)
    assert [d.name for d in gen.bench_law_dirs()] == ["you2019", "yao2020", "zhao2022"]


@pytest.mark.parametrize("folder", sorted(p.name for p in LAWS.iterdir() if (p / "law.eds").is_file()))
def test_a_papers_folder_passes_a_users_rules_but_the_range(folder: str, tmp_path: Path) -> None:
    """The same checks as a user's folder (one record, names, types, values, canopen's import); moved into the
    user's range, the same folder merges as a user's law."""
    gen = _gen_law()
    src = LAWS / folder
    names, index, _ = gen.merge_text(PLAIN_EDS.read_text(), src, _supported(), gen.BENCH_LAWS)
    assert names and index in gen.BENCH_LAWS
    with pytest.raises(gen.LawError, match=r"outside 0x2400\.\.0x24FF"):
        gen.merge_text(PLAIN_EDS.read_text(), src, _supported(), gen.USER_LAWS)
    as_user = tmp_path / folder
    shutil.copytree(src, as_user)
    frag = as_user / "law.eds"
    frag.write_text(re.sub(rf"^\[{index:04X}", f"[{index - 0x100:04X}", frag.read_text(), flags=re.M))
    assert gen.merge_text(PLAIN_EDS.read_text(), as_user, _supported(), gen.USER_LAWS)[:2] == (names, index - 0x100)


def test_a_fourth_paper_is_one_more_folder(tmp_path: Path) -> None:
    """A new folder beside the papers' (its record at 0x2503) becomes the next value of Controller.controller and a
    row of the generated registry; nothing else of the drive changes."""
    gen = _gen_law()
    laws = tmp_path / "laws"
    shutil.copytree(LAWS, laws)
    new = laws / "smith2030"
    shutil.copytree(LAWS / "zhao2022", new)
    text = (new / "law.eds").read_text()
    text = re.sub(r"^\[2502", "[2503", text, flags=re.M)
    text = text.replace("ParameterName=Zhao 2022", "ParameterName=Smith 2030")
    text = re.sub(r"^CurrentLaws=.*$", "CurrentLaws=deadbeat_smith2030", text, flags=re.M)
    text = re.sub(r"^(Results|Trace)\.predictive_zhao2022=.*\n", "", text, flags=re.M)
    text = re.sub(r"^(Results|Trace)\.\w+=", r"\1=", text, flags=re.M)
    (new / "law.eds").write_text(text)
    merged = gen.merge_all(PLAIN_EDS, None, _supported(), laws)
    before = _ini(BUILT_EDS.read_text())
    after = _ini(merged)
    assert after.get("2200sub1", "ValueNames") == before.get("2200sub1", "ValueNames") + ",deadbeat_smith2030"
    assert after.get("2200sub1", "DefaultValue") == before.get("2200sub1", "DefaultValue")
    assert set(after.sections()) - set(before.sections()) == {s for s in after.sections() if s.startswith("2503")}


def test_the_drive_core_knows_no_laws_feature() -> None:
    """drive_config_t keeps what every law needs: You 2019's pipeline settings live in its record (law.eds), and the
    drive's output guard takes what a law adds after its limit from the law's output, not from a law's setting."""
    pipeline = ("deadtime_comp", "estimator", "decoupling", "limited_memory", "pi_bandwidth")
    for name in ("drive_config.h", "drive_core.c", "drive_core.h", "current_law.h"):
        code = re.sub(r"/\*.*?\*/", "", (CORE / name).read_text(), flags=re.S)
        assert not [w for w in pipeline if w in code], name
    you = (LAWS / "you2019" / "law.eds").read_text()
    for entry in ("deadtime_comp_enable", "estimator_enable", "decoupling_enable", "limited_memory", "pi_bandwidth_Hz"):
        assert f"ParameterName={entry}\n" in you


def test_a_papers_law_traces_through_its_record(hil_run) -> None:  # type: ignore[no-untyped-def]
    """One trace path (issue 41): a law's quantities are its record's status entries, traced by PDO as a user's
    law's are; You 2019's estimator prediction i_hat_q(k) (Eq. 5-9), traced by name, is the current sampled two
    periods later in a matched ideal run. The law interface has no signals member and the drive's recorder knows
    the drive's own signals only."""
    scenario = {
        "scenario": {"name": "you2019-estimator-trace", "periods": 200},
        "motor": {"preset": "you2019", "mech_mode": "locked"},
        "drive": {"preset": "ideal"},
        "controller": {"controller": "deadbeat_you2019", "Vmax_V": 139.0},
        "trace": {"pdo3": ["Online tuning.i_hat_q_A", "Online tuning.i_hat_d_A"]},
        "events": [{"at_period": 20, "references": {"iq_ref_A": 1.0}}],
    }
    run = hil_run(scenario, bus="direct")
    run.expect_status("ok")
    t = run.traces
    iq, i_hat = t["iq_A"].astype(float), t["i_hat_q_A"].astype(float)
    assert abs(i_hat[20:190] - iq[22:192]).max() < 1e-5  # the prediction of k+2, at the step too
    assert abs(i_hat[20:190] - iq[20:190]).max() > 0.5  # not the present current
    law_face = re.sub(r"/\*.*?\*/", "", (CORE / "current_law.h").read_text(), flags=re.S)
    assert "signals" not in law_face and "trace_recorder" not in law_face
    recorder = (CORE / "trace_recorder.h").read_text()
    assert not re.search(r"you\s*_?2019|yao\s*_?2020|zhao\s*_?2022", recorder, re.IGNORECASE)


def test_a_default_law_that_names_no_law_is_refused(tmp_path: Path) -> None:
    """drive.eds' DefaultLaw must name a merged law: else the drive would start in open loop without a word."""
    gen = _gen_law()
    eds = tmp_path / "drive.eds"
    eds.write_text(PLAIN_EDS.read_text().replace("DefaultLaw=deadbeat_you2019", "DefaultLaw=deadbeat_you2091"))
    with pytest.raises(gen.LawError, match=r"\[2200sub1\]: DefaultLaw=deadbeat_you2091: not one of the merged laws"):
        gen.merge_all(eds, None, _supported())


def test_law_with_several_names_is_selected_by_any(monkeypatch: pytest.MonkeyPatch) -> None:
    """`--law DIR` of a folder whose record names several laws (BENCH_LAW=a,b): a scenario that selects any of them
    runs; one that selects none is refused naming them all."""
    from bench.scenario import load
    from bench.scenario.overrides import unselected_law

    monkeypatch.setenv("BENCH_LAW", "pi,deadbeat_you2019")
    step = REPO / "scenarios" / "you2019_step.toml"  # selects deadbeat_you2019
    assert unselected_law([load(step)]) is None
    refusal = unselected_law([load(step, ["controller.controller=dpcc_yao2020", "motor.preset=zhao2022"])])
    assert refusal is not None and "any of the laws pi, deadbeat_you2019" in refusal
