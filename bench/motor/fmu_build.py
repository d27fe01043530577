"""A source FMU built into a binary one (`bench motor fmu-build SRC OUT.fmu`): SRC holds modelDescription.xml and
sources/*.c (examples/fmu/linear_pmsm); its C is compiled for Linux x86-64 against the standard FMI headers (FMPy's
copy: the `fmu` extra) and zipped in the FMU layout (modelDescription.xml, binaries/linux64/ID.so, sources/).
FMPy's own builder needs CMake and a project per FMU; a C source FMU of a few files needs one compiler call."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from bench.extras import missing_extra


class FmuBuildError(RuntimeError):
    """The source FMU does not build: the message names the file and the compiler's words."""


def fmi_headers() -> Path:
    """FMPy's copy of the standard FMI 2.0/3.0 headers."""
    try:
        import fmpy
    except ImportError:
        raise FmuBuildError(missing_extra("fmu", "bench motor fmu-build", "FMPy is not installed")) from None
    return Path(os.path.dirname(fmpy.__file__)) / "c-code"


def build_source_fmu(src: Path, out: Path, cc: str = "cc") -> Path:
    desc = src / "modelDescription.xml"
    if not desc.is_file():
        raise FmuBuildError(f"{desc}: missing (a source FMU holds modelDescription.xml and sources/*.c)")
    try:
        root = ET.parse(desc).getroot()
    except ET.ParseError as exc:
        raise FmuBuildError(f"{desc}: not valid XML: {exc}") from None
    version = root.get("fmiVersion", "")
    cs = root.find("CoSimulation")
    if cs is None or not cs.get("modelIdentifier"):
        raise FmuBuildError(f"{desc}: no <CoSimulation modelIdentifier=...>: the bench runs co-simulation FMUs")
    ident = cs.get("modelIdentifier", "")
    platform = "linux64" if version.startswith("2") else "x86_64-linux"
    sources = sorted((src / "sources").glob("*.c"))
    if not sources:
        raise FmuBuildError(f"{src / 'sources'}: no C files")
    with tempfile.TemporaryDirectory(prefix="fmu-build-") as td:
        lib = Path(td) / "binaries" / platform / f"{ident}.so"
        lib.parent.mkdir(parents=True)
        argv = [cc, "-std=c11", "-O2", "-fPIC", "-shared", "-isystem", str(fmi_headers()), f"-I{src / 'sources'}"]
        argv += [str(s) for s in sources] + ["-lm", "-o", str(lib)]
        res = subprocess.run(argv, capture_output=True, text=True, check=False)
        if res.returncode != 0:
            raise FmuBuildError(f"{src}: the FMU's C does not compile:\n{res.stderr.strip()[-2000:]}")
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(out.name + ".part")
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            z.write(desc, "modelDescription.xml")
            z.write(lib, f"binaries/{platform}/{ident}.so")
            for s in sorted((src / "sources").iterdir()):  # its C files and headers (a link is stored as its file)
                if s.suffix in (".c", ".h"):
                    z.write(s.resolve(), f"sources/{s.name}")
        shutil.move(tmp, out)  # whole or not at all
    return out
