"""summary.json "motor": which motor a run's plant had, with a digest of its files (a CI result names its motor)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from bench.scenario import Scenario


def motor_block(sc: Scenario) -> dict[str, Any]:
    """summary.json "motor": the plant's motor as the run had it. A motor folder ([motor] folder, --motor DIR) or
    an FMU ([motor.fmu]): {"folder": its absolute path or null, "fmu": the .fmu's or null, "name": motor.toml's
    name or the FMU's model, "digest": 16 hex of the SHA-256 of its files} (the folder's motor.toml and the flux-map
    table it names; the .fmu file: an FMU's mapping and parameters are the scenario's). A built-in motor:
    {"builtin": its preset}."""
    from bench.motor.folder import DESCRIPTION

    if sc.motor_folder is not None:
        folder = Path(sc.motor_folder.path)
        files = [folder / DESCRIPTION, *([Path(sc.motor_folder.map_file)] if sc.motor_folder.map_file else [])]
        return {"folder": str(folder), "fmu": None, "name": sc.motor_folder.name, "digest": files_digest(folder, files)}
    if sc.motor_fmu is not None:
        fmu = Path(sc.motor_fmu.path)
        digest = files_digest(fmu.parent, [fmu])
        return {"folder": None, "fmu": str(fmu), "name": sc.motor_fmu.model_name, "digest": digest}
    return {"builtin": sc.preset}


def files_digest(base: Path, files: list[Path]) -> str | None:
    """16 hex of the SHA-256 of the files, each by its path from `base` and its bytes (bench.law.digest's way);
    None when one can no longer be read (removed during the run: the run's results are kept all the same)."""
    import hashlib

    h = hashlib.sha256()
    try:
        for f in files:
            h.update(os.path.relpath(f, base).encode() + b"\0" + f.read_bytes() + b"\0")
    except OSError:
        return None
    return h.hexdigest()[:16]
