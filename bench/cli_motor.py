"""`bench motor`: a user's motor folder (docs/YOUR_MOTOR.md) checked and summarised (check), or the example folder
written (example), a source FMU built (fmu-build). Its arguments and its handlers; its row of the command table
(bench/commands.py) names it and says what it is."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# the example folders' names (bench/motor/example.py EXAMPLES; a test keeps them equal): `bench --help` builds
# this parser without importing numpy
EXAMPLE_NAMES = ("saturating_you2019", "saturating_yao2020")


def _cmd_check(args: argparse.Namespace) -> int:
    import numpy as np

    from bench.motor import MotorError, load

    try:
        m = load(args.folder)
    except MotorError as exc:
        print(f"bench motor check: {exc}", file=sys.stderr)
        return 65
    print(f"{m.name}  ({m.path})")
    print(f"  source: {m.source}")
    fm = m.map
    if fm is None:  # the linear dq model or a model of its own table: the values as the plant is given them
        print(f"  model: {m.model} (no flux map)")
        print(f"  plant values: {', '.join(f'{k} = {v:g}' for k, v in m.values.items())}")
        return 0
    Ld, Lq, psi = fm.small_signal()
    print(
        f"  map: {m.map_file.name}, {len(fm.id_A)} x {len(fm.iq_A)} points, id {fm.id_A[0]:g} .. {fm.id_A[-1]:g} A, "
        f"iq {fm.iq_A[0]:g} .. {fm.iq_A[-1]:g} A: invertible"
    )
    print(
        f"  at zero current: Ld {Ld * 1e3:.4g} mH, Lq {Lq * 1e3:.4g} mH, psi {psi * 1e3:.4g} mWb "
        "(written as the plant's Ld_H, Lq_H, psi_Wb: what the drive is configured from)"
    )
    idg, iqg = np.meshgrid(fm.id_A, fm.iq_A, indexing="ij")
    e = fm.eval(idg, iqg)
    for name in ("Ldd_H", "Lqq_H"):
        v = e[name]
        print(f"  incremental {name[:3]} over the map: {v.min() * 1e3:.4g} .. {v.max() * 1e3:.4g} mH")
    extra = ", ".join(f"{k} = {v:g}" for k, v in m.values.items())
    print(f"  plant values: {extra}")
    from bench.motor.trip import describe

    for line in describe(m):
        print(f"  {line}")
    return 0


def _cmd_example(args: argparse.Namespace) -> int:
    from bench.motor.example import write_example

    try:
        folder = write_example(Path(args.folder), args.example)
    except FileExistsError as exc:
        print(f"bench motor example: {exc}", file=sys.stderr)
        return 73
    print(f"wrote {folder}/motor.toml and {folder}/flux_map.csv: run it with `bench run SCENARIO --motor {folder}`")
    return 0


def _cmd_fmu_build(args: argparse.Namespace) -> int:
    from bench.motor.fmu_build import FmuBuildError, build_source_fmu

    try:
        out = build_source_fmu(Path(args.source), Path(args.out))
    except FmuBuildError as exc:
        print(f"bench motor fmu-build: {exc}", file=sys.stderr)
        return 65
    print(f'wrote {out}: use it with [motor.fmu] file = "{out}" (docs/YOUR_MOTOR.md)')
    return 0


_SUBCOMMANDS = {"check": _cmd_check, "example": _cmd_example, "fmu-build": _cmd_fmu_build}


def cmd_motor(args: argparse.Namespace) -> int:
    """`bench motor SUBCOMMAND`: the subcommand's handler (motor_arguments makes one a must)."""
    return _SUBCOMMANDS[args.motor_command](args)


def motor_arguments(mo: argparse.ArgumentParser) -> None:
    ms = mo.add_subparsers(dest="motor_command", metavar="SUBCOMMAND", required=True)
    c = ms.add_parser(
        "check",
        help="read and check a motor folder, print what the plant will run",
        description="Reads motor.toml and the flux-map table and checks them as a run would (monotonic grids, "
        "finite values, an invertible map); each refusal names the file, the row and the value; exit 65.",
    )
    c.add_argument("folder", type=Path, help="the motor folder")
    ex = ms.add_parser(
        "example",
        help="write an example motor folder (a paper's motor with an assumed saturating flux map)",
        description="Writes motor.toml and flux_map.csv of the example motor (bench/motor/example.py: an "
        "analytic co-energy saturation model, its parameters ASSUMED) into FOLDER (created; refused when it "
        "already holds a motor.toml).",
    )
    ex.add_argument("folder", type=Path, help="where to write it")
    ex.add_argument(
        "--example",
        choices=EXAMPLE_NAMES,
        default=EXAMPLE_NAMES[0],
        help=f"which: a paper's motor with an assumed saturating map (default {EXAMPLE_NAMES[0]})",
    )
    fb = ms.add_parser(
        "fmu-build",
        help="build a C source FMU (modelDescription.xml + sources/*.c) into a Linux x86-64 co-simulation .fmu",
        description="Compiles SOURCE's sources/*.c against the standard FMI headers (FMPy's copy) into "
        "binaries/linux64/ID.so (FMI 2.0; x86_64-linux for 3.0) and zips the FMU; e.g. the bench's own linear "
        "PMSM: `bench motor fmu-build examples/fmu/linear_pmsm linear_pmsm.fmu`.",
    )
    fb.add_argument("source", type=Path, help="the source FMU's folder")
    fb.add_argument("out", type=Path, help="the .fmu to write")
