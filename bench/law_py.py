"""A current law prototyped in Python, run in the direct loop in place of a registered law (docs/YOUR_CONTROLLER.md
"Prototype in Python first").

The class has the C interface's face (firmware_shim/core/current_law.h), method for function:

    class MyLaw:
        law = "pi"                                   # the registered law it stands in for: its Controller.controller
                                                     # value name, whose EDS record configures it
        def configure(self, cfg, record, switched):  # cfg: DriveConfig (R_hat_ohm, Lq_hat_H, Vmax_V, Ts_s, ...)
        def step(self, cfg, record, i, out):         # i: LawIn (i_d_A, i_q_A, id_ref_A, iq_ref_A, theta_e_rad,
                                                     # omega_e_rad_s); out: LawOut, every field set
        def commit(self, cfg, record, i, applied):   # optional: told the command applied
        def reset(self):                             # optional: forget the memories
        def status(self, cfg, record):               # optional: write the record's status entries (traced, read)

cfg, i, out and record are ctypes views of the drive's own structs (bench/direct/hil_pylaw.c): a field read is a
Python float holding the float32 value, a field written is rounded to float32. A prototype that computes in float32
(numpy.float32 scalars, and bench.law_py.cosf/sinf/expf/sqrtf, the C library's) does the C port's arithmetic.

The drive does the rest as for a C law: the record's defaults and SDO writes, the check of a configuration (the law
it stands in for's), the command's checks (non-finite or beyond Vmax_V: law_fault) and the trace. An exception in a
method makes that step's command NaN, so the drive refuses it (law_fault) and the run goes on to its end with its
frames; the exception is named in the summary ("python_law") and on the console.
"""

from __future__ import annotations

import ctypes
import importlib
import importlib.util
import math
import sys
import traceback
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

from canopen.objectdictionary import datatypes

F = ctypes.c_float


class LawIn(ctypes.Structure):
    """current_law_in_t: sample k as the law sees it."""

    _fields_ = [
        ("i_d_A", F),
        ("i_q_A", F),
        ("id_ref_A", F),
        ("iq_ref_A", F),
        ("theta_e_rad", F),
        ("omega_e_rad_s", F),
    ]


class LawOut(ctypes.Structure):
    """current_law_out_t: the command; the drive applies v_alpha_V, v_beta_V."""

    _fields_ = [
        ("v_d_V", F),
        ("v_q_V", F),
        ("v_d_star_V", F),
        ("v_q_star_V", F),
        ("v_d_ff_V", F),
        ("v_q_ff_V", F),
        ("v_alpha_V", F),
        ("v_beta_V", F),
        ("v_limited", ctypes.c_uint8),
        ("v_after_limit_V", F),
    ]


class DriveConfig(ctypes.Structure):
    """drive_config_t up to its outer loops' configuration (what a current law reads)."""

    _fields_ = [
        ("controller", ctypes.c_uint8),
        ("Ts_s", F),
        ("speed_loop_divider", ctypes.c_uint16),
        ("R_hat_ohm", F),
        ("Ld_hat_H", F),
        ("Lq_hat_H", F),
        ("psi_hat_Wb", F),
        ("pole_pairs", F),
        ("Vmax_V", F),
        ("J_hat_kgm2", F),
        ("vlimit_radial", ctypes.c_uint8),
        ("angle_advance_periods", F),
    ]


# hil_pylaw_layout's figures, in its order: what the mirrors above must match
LAYOUT = (
    ctypes.sizeof(LawIn),
    LawIn.omega_e_rad_s.offset,
    ctypes.sizeof(LawOut),
    LawOut.v_beta_V.offset,
    LawOut.v_limited.offset,
    LawOut.v_after_limit_V.offset,
    DriveConfig.Ts_s.offset,
    DriveConfig.speed_loop_divider.offset,
    DriveConfig.R_hat_ohm.offset,
    DriveConfig.Ld_hat_H.offset,
    DriveConfig.Lq_hat_H.offset,
    DriveConfig.psi_hat_Wb.offset,
    DriveConfig.pole_pairs.offset,
    DriveConfig.Vmax_V.offset,
    DriveConfig.J_hat_kgm2.offset,
    DriveConfig.vlimit_radial.offset,
    DriveConfig.angle_advance_periods.offset,
)

C_TYPES = {
    datatypes.BOOLEAN: ctypes.c_uint8,
    datatypes.INTEGER8: ctypes.c_int8,
    datatypes.INTEGER16: ctypes.c_int16,
    datatypes.INTEGER32: ctypes.c_int32,
    datatypes.UNSIGNED8: ctypes.c_uint8,
    datatypes.UNSIGNED16: ctypes.c_uint16,
    datatypes.UNSIGNED32: ctypes.c_uint32,
    datatypes.REAL32: ctypes.c_float,
}


class LawError(ValueError):
    """A Python law that cannot stand in: no such class, no `law`, a law the drive does not have."""


def _libm() -> ctypes.CDLL:
    lib = ctypes.CDLL("libm.so.6")
    for name in ("cosf", "sinf", "expf", "sqrtf", "atan2f"):
        fn = getattr(lib, name)
        fn.restype = ctypes.c_float
        fn.argtypes = [ctypes.c_float] * (2 if name == "atan2f" else 1)
    return lib


_M = _libm()
# The C library's float32 functions, as a C port calls them (numpy's own float32 cos may differ in the last bit).
cosf, sinf, expf, sqrtf, atan2f = _M.cosf, _M.sinf, _M.expf, _M.sqrtf, _M.atan2f


def _ident(name: str) -> str:
    """An EDS ParameterName as the generated struct's field (protocols/odgen/c_types.py c_ident)."""
    import re

    s = re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_")
    s = s.lower() if " " in name else s
    return "_" + s if not s or s[0].isdigit() else s


@cache
def record_struct(law: str, eds: Path | None = None) -> type[ctypes.Structure] | None:
    """The ctypes mirror of law `law`'s record (its generated C struct: the entries in sub-index order), None for a
    law without one."""
    from bench.laws import law_record

    rec = law_record(law, eds)
    if rec is None:
        return None
    fields = []
    for sub in sorted(rec.subindices):
        var = rec.subindices[sub]
        if var.data_type not in C_TYPES:
            raise LawError(f"{rec.name}.{var.name}: data type {var.data_type:#x} has no C field")
        fields.append((_ident(var.name), C_TYPES[var.data_type]))
    return type(f"Record_{_ident(rec.name)}", (ctypes.Structure,), {"_fields_": fields})


def load_law(spec: str) -> Any:
    """An instance of the class `spec` names: "FILE.py:Class" (a path) or "module:Class" (importable); its module is
    imported once per process (a sweep's worker makes a new object a point)."""
    return law_class(spec)()


@cache
def law_class(spec: str) -> Any:
    """The class `spec` names (load_law)."""
    where, sep, name = spec.rpartition(":")
    if not sep or not where or not name:
        raise LawError(f"--py-law {spec!r}: expected FILE.py:Class or module:Class")
    if where.endswith(".py"):
        path = Path(where).expanduser().resolve()
        if not path.is_file():
            raise LawError(f"--py-law {spec!r}: no such file {path}")
        import hashlib

        mod_name = f"bench_py_law_{path.stem}_{hashlib.sha256(str(path).encode()).hexdigest()[:8]}"
        if str(path.parent) not in sys.path:  # its helper modules next to it import as from a script of that folder
            sys.path.insert(0, str(path.parent))
        loader = importlib.util.spec_from_file_location(mod_name, path)
        assert loader is not None and loader.loader is not None
        module = importlib.util.module_from_spec(loader)
        sys.modules[mod_name] = module
        loader.loader.exec_module(module)
    else:
        module = importlib.import_module(where)
    cls = getattr(module, name, None)
    if cls is None:
        raise LawError(f"--py-law {spec!r}: {where} has no {name}")
    return cls


def checked(obj: Any, spec: str | None) -> Any:
    """The law object (`obj`, else the class `spec` names, instantiated), checked against the build's laws."""
    try:
        law = obj if obj is not None else load_law(str(spec))
    except LawError:
        raise
    except Exception as exc:  # noqa: BLE001 - the user's module failing to import, its class to construct
        raise LawError(f"--py-law {spec}: {type(exc).__name__}: {exc}") from None
    law_value(law)
    return law


def law_value(obj: Any, eds: Path | None = None) -> int:
    """The Controller.controller value of the registered law `obj` stands in for (its `law` attribute)."""
    from bench.laws import law_names

    if isinstance(obj, type):
        raise LawError(f"py_law takes an instance of the law's class: {obj.__name__}(), not the class {obj.__name__}")
    names = law_names(eds)
    law = getattr(obj, "law", None)
    if not isinstance(law, str) or law not in names[1:]:
        have = ", ".join(names[1:])
        raise LawError(f"{type(obj).__name__}.law = {law!r}: name the registered law it stands in for ({have})")
    for method in ("configure", "step"):
        if not callable(getattr(obj, method, None)):
            raise LawError(f"{type(obj).__name__} has no {method}() (the C interface's face: docs/YOUR_CONTROLLER.md)")
    return names.index(law)


@dataclass
class Failure:
    """The first exception of the law's methods: where, at its how-manieth step, the exception and its traceback."""

    method: str
    step: int
    error: str
    traceback: str


@dataclass
class Calls:
    """A Python law in the loop: its callbacks into libhil (kept alive here), its steps, its first failure."""

    obj: Any
    record: type[ctypes.Structure] | None
    steps: int = 0
    failure: Failure | None = None
    interrupt: BaseException | None = None
    stop: Any = None  # asks the loop to return (hil_pylaw_interrupt)
    keep: list[Any] = field(default_factory=list)

    def fail(self, method: str, exc: BaseException) -> None:
        if not isinstance(exc, Exception):  # Ctrl-C, SystemExit: the caller's, raised once the loop returns
            self.interrupt = self.interrupt or exc
            if self.stop is not None:
                self.stop()
        if self.failure is None:
            text = "".join(traceback.format_exception(exc))
            self.failure = Failure(method, self.steps, f"{type(exc).__name__}: {exc}", text)

    def report(self, summary: dict[str, Any]) -> None:
        """Into a run's summary: "python_law" (its class, the law it stood in for, its steps, its first exception) and
        a note on that exception; a Ctrl-C during one of its methods is raised here, once the run's results are."""
        summary["python_law"] = self.summary()
        if self.failure is not None:
            f = self.failure
            summary.setdefault("notes", []).append(
                f"the Python law's {f.method}() raised {f.error} at its step {f.step}: its commands from then on were "
                "NaN, which the drive refused (law_fault); the traceback is in summary.json python_law.exception"
            )
        if self.interrupt is not None:
            raise self.interrupt

    def summary(self) -> dict[str, Any]:
        cls = type(self.obj)
        out: dict[str, Any] = {"class": f"{cls.__module__}.{cls.__qualname__}", "law": self.obj.law}
        out["steps"] = self.steps
        if self.failure is not None:
            f = self.failure
            out["exception"] = {"method": f.method, "at_step": f.step, "error": f.error, "traceback": f.traceback}
        return out


def nan_command(out: LawOut) -> None:
    """A command the drive refuses (non-finite: law_fault)."""
    out.v_alpha_V = out.v_beta_V = out.v_d_V = out.v_q_V = math.nan


V = ctypes.c_void_p
CONFIGURE = ctypes.CFUNCTYPE(None, V, V, ctypes.c_int32)
STEP = ctypes.CFUNCTYPE(None, V, V, V, V)
RESET = ctypes.CFUNCTYPE(None)
STATUS = ctypes.CFUNCTYPE(None, V, V)


class HilPyLaw(ctypes.Structure):
    """hil_pylaw_t: the callbacks (NULL: a method the class does not have)."""

    _fields_ = [("configure", CONFIGURE), ("step", STEP), ("commit", STEP), ("reset", RESET), ("status", STATUS)]


def _views(kind: type | None) -> Any:
    """The ctypes view of a `kind` struct at an address, made again only when the address changes (the drive's cfg,
    record and command stay where they are: a view a period would be most of a callback's cost)."""
    last: list[Any] = [None, None]

    def view(addr: int | None) -> Any:
        if addr != last[0]:
            last[0], last[1] = addr, (None if kind is None or addr is None else kind.from_address(addr))
        return last[1]

    return view


def _copy(kind: type | None, addr: int | None) -> Any:
    """A copy of the `kind` struct at `addr`: what the law reads and may not change (the C interface's const)."""
    return None if kind is None or addr is None else kind.from_buffer_copy(kind.from_address(addr))


def callbacks(calls: Calls) -> HilPyLaw:
    """The law's methods as C callbacks. What C gives a law as const (cfg, the record but in status(), the sample, the
    command applied) the method gets as a copy: a write to it changes nothing of the drive's, as in C it would not
    compile. cfg and the record are copied when the drive configures the law, which it does on any change of either.
    A method that raises is the law's failure (Calls.fail): from then on its commands are NaN and its other methods
    are not called."""
    obj, rec = calls.obj, calls.record
    out_v, rec_v = _views(LawOut), _views(rec)
    given: list[Any] = [None, None]  # the copies of cfg and the record of the last configure
    first = [True]  # the drive may have configured the registered law before this one stood in: a first start
    law_step = obj.step

    def configure(cfg: int, record: int | None, switched: int) -> None:
        given[0], given[1] = _copy(DriveConfig, cfg), _copy(rec, record)
        if calls.failure is None:
            try:
                obj.configure(given[0], given[1], bool(switched) or first[0])
                first[0] = False
            except BaseException as exc:  # noqa: BLE001 - the law's failure, named in the summary
                calls.fail("configure", exc)

    def step(cfg: int, record: int | None, i: int, out: int) -> None:
        calls.steps += 1
        o = out_v(out)
        if calls.failure is None:
            try:
                law_step(given[0], given[1], LawIn.from_buffer_copy(LawIn.from_address(i)), o)
                return
            except BaseException as exc:  # noqa: BLE001
                calls.fail("step", exc)
        nan_command(o)

    def commit(cfg: int, record: int | None, i: int, applied: int) -> None:
        if calls.failure is None:
            try:
                sample = LawIn.from_buffer_copy(LawIn.from_address(i))
                obj.commit(given[0], given[1], sample, LawOut.from_buffer_copy(LawOut.from_address(applied)))
            except BaseException as exc:  # noqa: BLE001
                calls.fail("commit", exc)

    def reset() -> None:
        if calls.failure is None:
            try:
                obj.reset()
            except BaseException as exc:  # noqa: BLE001
                calls.fail("reset", exc)

    def status(cfg: int, record: int | None) -> None:
        if calls.failure is None:
            try:
                obj.status(given[0], rec_v(record))  # its status entries: the record the drive shows and traces
            except BaseException as exc:  # noqa: BLE001
                calls.fail("status", exc)

    cb = HilPyLaw(CONFIGURE(configure), STEP(step))
    if callable(getattr(obj, "commit", None)):
        cb.commit = STEP(commit)
    if callable(getattr(obj, "reset", None)):
        cb.reset = RESET(reset)
    if callable(getattr(obj, "status", None)):
        cb.status = STATUS(status)
    return cb
