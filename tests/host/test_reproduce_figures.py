"""`bench reproduce`'s report shows each claim with its own runs: a claim function that returns
several results names the run(s) of each (ClaimResult.runs), the report's section of a claim links
only those runs, and the runs' figures and Rerun recordings are made from the trace each run decoded
(its traces.npy: the log is not decoded again). Direct mode, one fast claim function (two 120-period runs)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from bench import claims
from bench import reproduce as rep
from bench.claims import ClaimResult, run_raw
from bench.claims import you2019 as y


@pytest.fixture()
def run_root(tmp_path: Path) -> Iterator[Path]:
    old = claims.RUN_ROOT
    claims.RUN_ROOT = tmp_path / "runs"
    claims.RUN_ROOT.mkdir()
    try:
        yield tmp_path
    finally:
        claims.RUN_ROOT = old
        claims.RUNS_USED.clear()


def _sections(text: str, start: str, stop: str) -> dict[str, str]:
    """claim_id -> the text of its section (markdown '### id: ...' or html "<section id='id'")."""
    parts = re.split(start, text)
    out = {}
    for i in range(1, len(parts), 2):
        out[parts[i]] = parts[i + 1].split(stop)[0] if stop else parts[i + 1]
    return out


def _linked_runs(section: str) -> set[str]:
    return set(re.findall(r"runs/([^/'\")]+)/", section))


def test_each_claim_shows_its_own_runs(run_root: Path) -> None:
    recs = rep.run_claim_function(y.claim_inductance_mismatch, "direct", "000", "You 2019")
    assert [r["claim_id"] for r in recs] == ["you2019-3-L0.5", "you2019-3-L1.2"]
    for r in recs:
        ratio = r["claim_id"].split("-L")[1]
        assert r["runs"] == [f"you2019-Lhat-{ratio}"], r["runs"]
    for r in recs:  # the claim's run wrote its trace as it decoded it, nothing else yet
        run = run_root / "runs" / r["runs"][0]
        assert (run / "traces.npy").stat().st_size > 0 and not (run / "run.rrd").exists()
    assert rep.make_views(run_root) == 0
    for r in recs:
        run = run_root / "runs" / r["runs"][0]
        for f in ("bus.log", "summary.json", "traces.npy", "run.rrd", "overview.png"):
            assert (run / f).stat().st_size > 0, (run, f)
    rep.write_reports(run_root, recs, "direct", 1.0)
    md = _sections((run_root / "report.md").read_text(), r"\n### (\S+): ", "")
    html = _sections((run_root / "report.html").read_text(), r"<section id='([^']+)'", "</section>")
    for r in recs:
        for name, sections in (("md", md), ("html", html)):
            linked = _linked_runs(sections[r["claim_id"]])
            assert linked == set(r["runs"]), (name, r["claim_id"], linked)
        assert f"![{r['runs'][0]}](runs/{r['runs'][0]}/overview.png)" in md[r["claim_id"]]


def test_several_results_without_their_runs_get_no_figure(run_root: Path) -> None:
    """A function whose results do not say their runs: no figure rather than another claim's."""

    def two_results(bus: str) -> list[ClaimResult]:
        run_raw(y.base("you2019-two-results"), bus)
        return [ClaimResult("You 2019", f"t-{i}", "-", "-", 0, 0, "-", True) for i in range(2)]

    def one_result(bus: str) -> ClaimResult:
        run_raw(y.base("you2019-one-result"), bus)
        return ClaimResult("You 2019", "t-one", "-", "-", 0, 0, "-", True)

    assert [r["runs"] for r in rep.run_claim_function(two_results, "direct", "000", "You 2019")] == [[], []]
    assert rep.run_claim_function(one_result, "direct", "000", "You 2019")[0]["runs"] == ["you2019-one-result"]


def _args(*argv: str) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    rep.add_arguments(p)
    return p.parse_args(list(argv))


def test_out_refuses_a_non_empty_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    keep = tmp_path / "mine" / "thesis.tex"
    keep.parent.mkdir()
    keep.write_text("precious")
    assert rep.main(_args("--paper", "000", "--bus", "direct", "--out", str(keep.parent))) == 2
    assert str(keep.parent) in capsys.readouterr().err
    assert keep.read_text() == "precious" and sorted(keep.parent.iterdir()) == [keep]
    # a previous report is not replaced either (only --publish replaces one)
    (keep.parent / "report.json").write_text("{}")
    assert rep.main(_args("--paper", "000", "--bus", "direct", "--out", str(keep.parent))) == 2
    # --publish into someone's folder is refused before anything runs
    out = tmp_path / "new"
    assert rep.main(_args("--paper", "000", "--bus", "direct", "--out", str(out), "--publish", str(tmp_path))) == 2
    assert not out.exists()
