"""Reading a Rerun recording back in tests (rerun 0.41 has no rr.dataframe; its chunk reader)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader


def read_recording(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """entity path -> {"period", "sim_time_ns", "value"}, concatenated over the chunks in period order."""
    reader = RrdReader(path)
    parts: dict[str, list[pa.RecordBatch]] = {}
    for chunk in reader.stream(store=reader.recordings()[0]):
        if chunk.is_static or "period" not in chunk.timeline_names:
            continue
        parts.setdefault(chunk.entity_path, []).append(chunk.to_record_batch())
    out = {}
    for path_, batches in parts.items():
        period = np.concatenate([b.column("period").to_numpy() for b in batches])
        sim_ns = np.concatenate([b.column("sim_time").cast(pa.int64()).to_numpy() for b in batches])
        values = []
        for b in batches:
            lists = b.column("Scalars:scalars")
            assert all(len(x) == 1 for x in lists.to_pylist()[:3])
            values.append(lists.flatten().to_numpy(zero_copy_only=False))
        value = np.concatenate(values)
        order = np.argsort(period, kind="stable")
        out[path_] = {"period": period[order], "sim_time_ns": sim_ns[order], "value": value[order]}
    return out
