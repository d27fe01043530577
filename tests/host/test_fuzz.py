"""Bounded libFuzzer run of the C CANopen slave under ASan + UBSan (protocols/fuzz/fuzz_slave.c).

Seeds come from the golden frame vectors, so the fuzzer starts from real SDO, NMT,
SYNC and PDO traffic. Any sanitizer finding or broken invariant (the harness aborts)
fails the test; the number of executions is printed.
"""

from __future__ import annotations

import re
import shutil
import struct
import subprocess

from bench.paths import BUILD, REPO
from bench.tools.vectors import load_vectors

FUZZ_SECONDS = 25


def _seed_corpus() -> list[bytes]:
    seeds = []
    for vec in load_vectors().values():
        blob = bytearray([0 if vec.node == "drive" else 1])
        for kind, frame in vec.steps:
            if kind == ">":
                blob += struct.pack("<HB", frame.cob_id, len(frame.data)) + frame.data.ljust(8, b"\0") + b"\x01"
        seeds.append(bytes(blob))
    return seeds


def test_past_findings_stay_fixed() -> None:
    """Each input the fuzzer once found is run alone: it must pass now."""
    build = subprocess.run(["make", "-s", "-C", str(REPO), "fuzz"], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr
    regs = sorted((REPO / "protocols" / "fuzz" / "regressions").glob("*"))
    assert regs
    res = subprocess.run(
        [str(BUILD / "fuzz" / "fuzz_slave"), *map(str, regs)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr[-2000:]


def test_fuzz_slave_bounded_run_is_clean() -> None:
    build = subprocess.run(["make", "-s", "-C", str(REPO), "fuzz"], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr
    corpus = BUILD / "fuzz" / "corpus"
    shutil.rmtree(corpus, ignore_errors=True)
    corpus.mkdir(parents=True)
    for i, seed in enumerate(_seed_corpus()):
        (corpus / f"seed{i:02d}").write_bytes(seed)
    # Inputs of past findings stay in the corpus (and are re-run first).
    for reg in sorted((REPO / "protocols" / "fuzz" / "regressions").glob("*")):
        shutil.copy(reg, corpus / f"regression-{reg.name}")
    artifacts = BUILD / "fuzz" / "artifacts"
    shutil.rmtree(artifacts, ignore_errors=True)
    artifacts.mkdir()
    res = subprocess.run(
        [
            str(BUILD / "fuzz" / "fuzz_slave"),
            f"-max_total_time={FUZZ_SECONDS}",
            "-rss_limit_mb=2048",
            "-max_len=600",
            "-print_final_stats=1",
            f"-artifact_prefix={artifacts}/",
            str(corpus),
        ],
        capture_output=True,
        text=True,
        timeout=FUZZ_SECONDS + 120,
    )
    tail = res.stderr[-3000:]
    runs = re.search(r"Done (\d+) runs", res.stderr)
    execs = re.search(r"stat::number_of_executed_units:\s*(\d+)", res.stderr)
    print(f"fuzz_slave: {execs[1] if execs else '?'} executions in {FUZZ_SECONDS} s")
    assert res.returncode == 0, tail
    assert runs is not None, tail
    assert int(runs[1]) > 10000, f"too few executions: {runs[1]}"
    assert not any(artifacts.iterdir()), f"crash artifacts: {list(artifacts.iterdir())}"
