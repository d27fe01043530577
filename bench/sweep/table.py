"""The study's table: rows stream to Parquet as points complete, so that a killed sweep loses at most
the last few seconds and `--resume` can skip what is done.

While the sweep runs, rows go to `sweep.parts/part-NNNNNN.parquet`, each a complete Parquet file
written under a temporary name and renamed (a kill never leaves half a file). At the end the parts
become one `sweep.parquet` in the study's point order (and `sweep.csv` on request); the parts are
removed. `read_done` reads whatever is there (the final table, parts, or both).
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

TABLE = "sweep.parquet"
PARTS = "sweep.parts"


def _table(rows: list[dict[str, Any]]) -> pa.Table:
    return pa.Table.from_pylist(rows)


def _concat(tables: list[pa.Table]) -> pa.Table:
    tables = [t for t in tables if t.num_rows]
    if not tables:
        return pa.table({})
    # a column missing from a part (e.g. identified values of another controller) becomes null there
    return pa.concat_tables(tables, promote_options="permissive")


def read_done(out: Path) -> pa.Table:
    """Every row already in the folder: the final table and any parts a killed sweep left."""
    tables = []
    if (out / TABLE).exists():
        tables.append(pq.read_table(out / TABLE))
    parts = out / PARTS
    if parts.is_dir():
        tables += [pq.read_table(p) for p in sorted(parts.glob("part-*.parquet"))]
    t = _concat(tables)
    if t.num_rows and "point_id" in t.column_names:
        # a point written twice (a part and the final table after a kill in between): keep the first
        seen: set[str] = set()
        keep = []
        for i, pid in enumerate(t.column("point_id").to_pylist()):
            if pid not in seen:
                seen.add(pid)
                keep.append(i)
        t = t.take(keep)
    return t


class TableWriter:
    """Collects rows and writes a part every `flush_s` seconds (and at close)."""

    def __init__(self, out: Path, flush_s: float = 1.0) -> None:
        self.out = out
        self.parts = out / PARTS
        self.parts.mkdir(parents=True, exist_ok=True)
        existing = sorted(self.parts.glob("part-*.parquet"))
        self._n = int(existing[-1].stem.split("-")[1]) + 1 if existing else 0
        self._rows: list[dict[str, Any]] = []
        self._last = time.monotonic()
        self.flush_s = flush_s
        self.written = 0

    def add(self, rows: list[dict[str, Any]]) -> None:
        self._rows += rows
        if time.monotonic() - self._last >= self.flush_s:
            self.flush()

    def flush(self) -> None:
        self._last = time.monotonic()
        if not self._rows:
            return
        path = self.parts / f"part-{self._n:06d}.parquet"
        tmp = path.with_suffix(".tmp")
        pq.write_table(_table(self._rows), tmp)
        os.replace(tmp, path)
        self._n += 1
        self.written += len(self._rows)
        self._rows = []

    def finish(self, order: list[str], csv: bool) -> pa.Table:
        """One table in the study's point order (`order`: point_ids), written atomically; parts removed."""
        self.flush()
        t = read_done(self.out)
        if t.num_rows:
            rank = {pid: i for i, pid in enumerate(order)}
            pids = t.column("point_id").to_pylist()
            idx = sorted(range(t.num_rows), key=lambda i: rank.get(pids[i], len(rank) + i))
            t = t.take(idx)
        tmp = self.out / (TABLE + ".tmp")
        pq.write_table(t, tmp)
        os.replace(tmp, self.out / TABLE)
        shutil.rmtree(self.parts, ignore_errors=True)
        if csv:
            pacsv.write_csv(t, self.out / "sweep.csv")
        return t
