"""A current law's results and default trace come from its record in drive.eds (bench/laws.py): the
papers' laws as before, and a user's law merged into drive.eds with no Python edit."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from bench.paths import EDS_DIR

USER_INDEX = 0x2400
USER_RECORD = "My law"
STATUS = ("err_A", "updates", "L_est_H")  # sub 3..5, read-only; L_est_H valid only after an update


def _entry(sub: int, name: str, dtype: str, access: str, extra: str = "") -> str:
    return (
        f"[{USER_INDEX:04X}sub{sub:X}]\nParameterName={name}\nObjectType=0x7\nDataType={dtype}\n"
        f"AccessType={access}\nDefaultValue=0\nPDOMapping={int(access == 'ro')}\n{extra}\n"
    )


def _fragment(valid_if: str, note: str | None) -> str:
    """Record 0x2400 of law my_law: two parameters, three status entries (one with ValidIf)."""
    notes = f"NotApplicableNote={note}\n" if note else ""
    return (
        f"[{USER_INDEX:04X}]\nParameterName={USER_RECORD}\nCurrentLaws=my_law\nObjectType=0x9\nSubNumber=6\n\n"
        + _entry(0, "Highest sub-index supported", "0x0005", "ro").replace("DefaultValue=0", "DefaultValue=5")
        + _entry(1, "gain_V_A", "0x0008", "rw")
        + _entry(2, "enable", "0x0005", "rw")
        + _entry(3, STATUS[0], "0x0008", "ro")
        + _entry(4, STATUS[1], "0x0007", "ro", notes if valid_if == "updates" else "")
        + _entry(5, STATUS[2], "0x0008", "ro", f"ValidIf={valid_if}\n")
    )


def merged_eds(tmp_path: Path, valid_if: str = "updates", note: str | None = None) -> Path:
    """drive.eds with my_law as value 6 of Controller.controller and its record 0x2400 (the fragment a
    user adds; the build merges it the same way)."""
    text = (EDS_DIR / "drive.eds").read_text()
    sec = re.search(r"^\[2200sub1\]\n(?:.+\n)*", text, re.M)
    assert sec is not None
    names = re.search(r"^ValueNames=(.*)$", sec.group(0), re.M)
    assert names is not None
    law_value = len(names.group(1).split(","))
    body = sec.group(0).replace(names.group(0), f"{names.group(0)},my_law")
    body = re.sub(r"^HighLimit=\d+$", f"HighLimit={law_value}", body, flags=re.M)
    text = text.replace(sec.group(0), body)
    count = re.search(r"^\[ManufacturerObjects\]\nSupportedObjects=(\d+)\n", text, re.M)
    assert count is not None
    n = int(count.group(1)) + 1
    listed = f"[ManufacturerObjects]\nSupportedObjects={n}\n{n}=0x{USER_INDEX:04X}\n"
    text = text.replace(count.group(0), listed) + "\n" + _fragment(valid_if, note)
    path = tmp_path / "drive.eds"
    path.write_text(text)
    return path


def _decoder(values: dict[tuple[str, str], float]) -> Any:
    """What identified() reads of a decoder: the drive's values as the bus showed them."""
    return SimpleNamespace(sdo=SimpleNamespace(drive=SimpleNamespace(get=lambda obj, sub: values.get((obj, sub)))))


def test_a_user_law_reports_and_traces_its_own_status(tmp_path: Path) -> None:
    from bench.laws import law_info, law_names, result_reads
    from bench.run.verdict.summary import format_identified, identified

    eds = merged_eds(tmp_path)
    value = law_names(eds).index("my_law")
    info = law_info("my_law", eds)
    assert (info.source, info.record, info.results) == (None, USER_RECORD, STATUS)
    assert info.trace == {3: tuple(f"{USER_RECORD}.{s}" for s in STATUS[:2]), 4: (f"{USER_RECORD}.{STATUS[2]}",)}
    assert ("drive", USER_RECORD, STATUS) in result_reads(eds)

    read = {("Controller", "controller"): value, (USER_RECORD, "err_A"): 0.25, (USER_RECORD, "updates"): 3}
    read[(USER_RECORD, "L_est_H")] = 0.5
    ident = identified(_decoder(read), eds)
    assert ident == {"controller": "my_law", "paper": None, "err_A": 0.25, "updates": 3, "L_est_H": 0.5}
    assert list(ident) == ["controller", "paper", *STATUS]
    assert format_identified(ident).startswith("identified (my_law): err_A 0.25, updates 3, L_est_H 0.5")

    read[(USER_RECORD, "updates")] = 0  # no update: its estimate does not apply
    assert identified(_decoder(read), eds) == {**ident, "updates": 0, "L_est_H": None}


def test_a_user_law_validif_on_a_parameter_and_its_note(tmp_path: Path) -> None:
    """ValidIf naming a parameter (known from its writes or its EDS default, not read at the end);
    a NotApplicableNote on the condition becomes the summary's note."""
    from bench.laws import law_info, law_names, result_reads
    from bench.run.verdict.summary import identified

    eds = merged_eds(tmp_path, valid_if="enable")
    assert law_info("my_law", eds).valid_if == {"L_est_H": "enable"}
    assert ("drive", USER_RECORD, STATUS) in result_reads(eds)  # the parameter is not read again
    read = {("Controller", "controller"): law_names(eds).index("my_law"), (USER_RECORD, "L_est_H"): 0.5}
    assert identified(_decoder(read), eds)["L_est_H"] is None
    assert identified(_decoder({**read, (USER_RECORD, "enable"): 1}), eds)["L_est_H"] == 0.5

    (tmp_path / "noted").mkdir()
    noted = merged_eds(tmp_path / "noted", note="never updated")
    ident = identified(_decoder({**read, (USER_RECORD, "updates"): 0}), noted)
    assert (ident["note"], ident["L_est_H"], list(ident)[2]) == ("never updated", None, "note")
    assert "note" not in identified(_decoder({**read, (USER_RECORD, "updates"): 2}), noted)


def test_a_status_valid_if_not_among_the_results_is_read_at_the_end(tmp_path: Path) -> None:
    from bench.laws import result_reads

    eds = merged_eds(tmp_path)
    text = eds.read_text().replace("[2400]\nParameterName=My law\n", "[2400]\nParameterName=My law\nResults=L_est_H\n")
    eds.write_text(text)
    assert ("drive", USER_RECORD, ("L_est_H", "updates")) in result_reads(eds)


def test_a_law_without_results_identifies_nothing_and_traces_the_drive_view(tmp_path: Path) -> None:
    """The PI shares You 2019's record (its pipeline settings) with empty Results.pi= and Source.pi= and the
    drive's view as Trace.pi= (firmware_shim/laws/you2019/law.eds)."""
    from bench.laws import DRIVE_VIEW, law_info
    from bench.run.verdict.summary import identified

    eds = merged_eds(tmp_path)
    pi = law_info("pi", eds)
    assert pi.record == law_info("deadbeat_you2019", eds).record and pi.results == () and pi.source is None
    assert pi.trace == DRIVE_VIEW
    ident = identified(_decoder({("Controller", "controller"): 1}), eds)
    assert ident == {"controller": "pi", "paper": None, "note": "not applicable: the pi controller identifies nothing"}


@pytest.mark.parametrize("law", ["deadbeat_you2019", "dpcc_yao2020", "incremental_zhao2022", "predictive_zhao2022"])
def test_the_papers_laws_read_their_results_in_order(law: str) -> None:
    """The end reads are a tuple in law order (not a set): the same on every run; each law's results
    are read with its record."""
    from bench.laws import law_info
    from bench.run.loop.reads import END_READS

    info = law_info(law)
    assert info.source is not None and info.record is not None and info.results
    assert ("drive", info.record, info.results) in END_READS
    assert isinstance(END_READS, tuple) and len(set(END_READS)) == len(END_READS)


def test_an_unknown_result_name_is_refused(tmp_path: Path) -> None:
    from bench.laws import law_info

    eds = merged_eds(tmp_path)
    eds.write_text(eds.read_text().replace("CurrentLaws=my_law\n", "CurrentLaws=my_law\nResults=nope\n"))
    with pytest.raises(KeyError, match="nope"):
        law_info("my_law", eds)


def test_the_end_reads_are_in_the_same_order_in_every_process() -> None:
    """END_READS is built in law order, not from a set: the same under any string hash seed."""
    import os
    import subprocess
    import sys

    code = "from bench.run.loop.reads import END_READS; print(END_READS)"
    seen = {
        subprocess.run(
            [sys.executable, "-c", code],
            env={**os.environ, "PYTHONHASHSEED": str(seed)},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for seed in range(6)
    }
    assert len(seen) == 1, seen
