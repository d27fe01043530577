"""`bench ... --law DIR`: build a user's current law (a folder: C files and law.eds) and run with it.

`make LAW=DIR` builds the drive with the law (the Makefile; gen_od.py --law merges law.eds into drive.eds) into
laws/<law name>-<hash of DIR's path>/ of the bench's working folder (bench/root.py STATE: build/ in a clone); the
command then runs with that build: BENCH_BUILD_DIR (bench/paths.py)
points the node binaries, libhil.so, the MCU image and the EDS files at it. The CLI does this before any
module reads an EDS (bench/cli.py). Nothing is written in the user's folder.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from bench.law_upgrade import explain
from bench.root import REPO, STATE  # not bench.paths: it reads BENCH_BUILD_DIR once, at import

COMMANDS = ("run", "sweep", "faults", "replay", "port-check")  # the commands that take --law
HELP = (
    "a user's current law: a folder of C files (and headers) and law.eds (one record in 0x2400..0x24FF naming "
    "the law in CurrentLaws=NAME, as the papers' folders firmware_shim/laws/*/ do); built first (make LAW=DIR "
    "into build/laws/NAME-<hash of DIR>/), then used: "
    'select it with [controller] controller = "NAME" (docs/YOUR_CONTROLLER.md)'
)
CURRENT_LAWS = re.compile(r"^\s*CurrentLaws\s*=\s*([A-Za-z0-9_,\t ]*)", re.MULTILINE)
COMPILE = re.compile(r"\s-c\s+(\S+\.c)\s+-o\s")
ERROR_LINES = 12


class LawBuildError(Exception):
    """The law does not build: the message names the user's file (or what the folder lacks)."""


def take_law(argv: list[str]) -> tuple[Path | None, list[str]]:
    """The --law DIR of a command that takes it, and argv without it."""
    if not argv or argv[0] not in COMMANDS:
        return None, argv
    rest, law = [argv[0]], None
    it = iter(argv[1:])
    for a in it:
        if a == "--":
            rest += [a, *it]
            break
        if a == "--law":
            law = next(it, None)
            if law is None:
                raise LawBuildError("--law needs a folder")
        elif a.startswith("--law="):
            law = a.split("=", 1)[1]
        else:
            rest.append(a)
    return (None if law is None else Path(law)), rest


def law_name(law: Path) -> str:
    """The folder's (first) law name: its build folder's name, the law a hil_run selects."""
    return law_names_of(law)[0]


def law_names_of(law: Path) -> tuple[str, ...]:
    """Every law the folder's record names (CurrentLaws=a,b: laws sharing the record)."""
    frag = law / "law.eds"
    if not law.is_dir():
        raise LawBuildError(f"{law}: no such folder")
    if not frag.is_file():
        raise LawBuildError(f"{frag}: missing (a law folder holds its C files and one EDS fragment, law.eds)")
    m = CURRENT_LAWS.search(frag.read_text())
    names = tuple(n.strip() for n in (m.group(1) if m else "").split(",") if n.strip())
    if not names:
        raise LawBuildError(f"{frag}: no CurrentLaws=<law name> key in its record's section")
    return names


def build(law: Path, repo: Path = REPO, state: Path = STATE, goals: tuple[str, ...] = ()) -> Path:
    """`make LAW=law [goals]` with progress on stderr; the build folder, or LawBuildError.

    Atomic: make works in the law's own work folder (laws/.<name>-<hash>.work, its objects kept for the next
    build), and only a build that succeeded is published, swapped in as laws/<name>-<hash>/ by two renames. A
    failing build leaves the previous good one as it was; a first build that fails leaves nothing. One lock,
    laws/.lock, serialises the builds (two CI jobs, pytest-xdist workers): each make uses every core anyway."""
    law = Path(os.path.abspath(law))  # not resolve(): a link from a path without white space stays one
    if re.search(r"\s", str(law)):
        raise LawBuildError(
            f"{law}: a law folder's path must not contain white space (make cannot take it): link the folder "
            "from a path without (ln -s '<folder>' /tmp/my_law; --law /tmp/my_law)"
        )
    name = law_name(law)
    out = build_folder(law, name, state)
    work = _work(out)
    cmd = ["make", "-C", str(repo), f"LAW={law}", f"BUILD={work}", f"PYTHON={sys.executable}"]
    # always every drive target (the published build is whole); an explicit goal (mcu) is asked for too, so that
    # make says what it lacks (no arm-none-eabi-gcc) instead of leaving the image out
    cmd += [f"-j{os.cpu_count() or 1}", *dict.fromkeys(("law", *goals))]
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(out.parent / ".lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # another command building now: after it, make finds its part done
            _prune(out, name)
            lines, compiled = _make(cmd, f"bench: building law {name} from {law} into {out} (make LAW=...)")
            if lines is not None:
                if not out.is_dir():
                    shutil.rmtree(work, ignore_errors=True)  # no good build to keep objects for
                raise LawBuildError(_failure(lines, law))
            if not _current(work, out):
                _publish(work, out)
            elif not compiled:
                print(f"bench: law {name} from {law}: its build {out} is current", file=sys.stderr, flush=True)
    except OSError as exc:
        where = exc.filename or out
        raise LawBuildError(
            f"cannot build in {where}: {exc.strerror} (make and a C compiler are needed; the build goes to the "
            "bench's working folder: BENCH_CACHE_DIR chooses another for an installed package)"
        ) from None
    return out


def _work(out: Path) -> Path:
    return out.with_name(f".{out.name}.work")


# what a run takes from a build (bench/paths.py): the objects, archives and dependency files stay in the work folder
NOT_PUBLISHED = ("obj", "deps", "*.o", "*.d", "*.a", "*.err")


def _published(work: Path) -> list[Path]:
    skip = shutil.ignore_patterns(*NOT_PUBLISHED)
    found: list[Path] = []
    for d, dirs, files in os.walk(work):
        drop = skip(d, [*dirs, *files])
        dirs[:] = [x for x in dirs if x not in drop]
        found += [Path(d, f) for f in files if f not in drop]
    return found


def _current(work: Path, out: Path) -> bool:
    """The published build holds the work folder's every output, as built (size and time)."""
    for f in _published(work):
        there = out / f.relative_to(work)
        try:
            a, b = f.stat(), there.stat()
        except OSError:
            return False
        if (a.st_size, a.st_mtime_ns) != (b.st_size, b.st_mtime_ns):
            return False
    return True


def _publish(work: Path, out: Path) -> None:
    """The work folder's outputs copied to a new folder, then swapped in for the published one."""
    new, old = out.with_name(f".{out.name}.new"), out.with_name(f".{out.name}.old")
    shutil.rmtree(new, ignore_errors=True)
    shutil.rmtree(old, ignore_errors=True)
    shutil.copytree(work, new, ignore=shutil.ignore_patterns(*NOT_PUBLISHED), symlinks=True)
    if out.is_dir():
        os.rename(out, old)
    os.rename(new, out)
    shutil.rmtree(old, ignore_errors=True)


def _make(cmd: list[str], header: str) -> tuple[list[str] | None, int]:
    """Run make with the compiled files shown on stderr (after `header`, once, when make compiles anything: a
    build that is current says so in one line instead); (None when it succeeded, else its output's lines; the
    number of files compiled)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    compiled = 0
    assert proc.stdout is not None
    for line in proc.stdout:
        lines.append(line.rstrip("\n"))
        m = COMPILE.search(line)
        if m:
            if not compiled:
                print(header, file=sys.stderr, flush=True)
            compiled += 1
            image = " (Cortex-M4F image)" if line.lstrip().startswith("arm-none-eabi-") else ""
            print(f"  cc {m.group(1)}{image}", file=sys.stderr, flush=True)
    return (None if proc.wait() == 0 else lines), compiled


def _prune(out: Path, name: str) -> None:
    """The builds of this law's name whose folder is gone (a test's temporary copy, a deleted checkout): removed
    with their work folders, so that one folder per law folder does not pile up; and what older versions of the
    bench left: per-build lock files, and `make LAW=`'s own laws/<name>/ when its folder is gone."""
    laws = out.parent
    for lock in laws.glob("?*.lock"):  # not .lock, the one lock of every build (held now)
        if lock.name != ".lock":
            lock.unlink(missing_ok=True)
    for other in [laws / name, *laws.glob(f"{name}-*"), *laws.glob(f".{name}-*.work")]:  # laws/<name>: make's, before
        source = other / "law.from"
        try:
            gone = other not in (out, _work(out)) and other.is_dir() and not Path(source.read_text().strip()).is_dir()
        except OSError:
            continue
        if gone:
            shutil.rmtree(other, ignore_errors=True)


def build_folder(law: Path, name: str, state: Path = STATE) -> Path:
    """laws/<law name>-<8 hex of the folder's path>: a folder of its own per law folder, so that two folders of the
    same law name (a copy under change, two CI jobs on one machine) never build over each other's binaries."""
    return state / "laws" / f"{name}-{hashlib.sha256(str(law).encode()).hexdigest()[:8]}"


def digest(law: Path) -> str:
    """The law folder's content (its law.eds, C files and header, by name): 16 hex of their SHA-256."""
    h = hashlib.sha256()
    for f in sorted(law.iterdir()):
        if f.is_file() and (f.name == "law.eds" or f.suffix in (".c", ".h")):
            h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


DIAGNOSTIC = re.compile(r": (fatal )?error: |undefined reference to ")
LOCATED = re.compile(r"^\S+:\d+:\d+: (fatal )?error: .*$")
MAKE_ERROR = re.compile(r"^Makefile:\d+: \*\*\* (.*?)\.?  Stop\.$")


def _failure(lines: list[str], law: Path) -> str:
    """The first lines that say why: gen_od's refusal, the Makefile's, the missing descriptor, else the
    compiler's first error lines (they name the user's file), after what changed in the law interface when they
    name a part of it that a version removed (bench/law_upgrade.py)."""
    for line in lines:
        if line.startswith("gen_od:") and not line.startswith("gen_od: wrote"):
            return line
        m = MAKE_ERROR.match(line)
        if m:
            return m.group(1)
        if line.startswith("make: LAW="):  # the descriptor's checks (the symbol, law_check.c)
            return "\n".join(re.sub(r"^make: LAW=\S+: ", "", ln) for ln in lines if ln.startswith("make: LAW="))
    errors = [i for i, line in enumerate(lines) if DIAGNOSTIC.search(line)]
    if not errors:
        return "make failed:\n" + "\n".join(lines[-ERROR_LINES:])
    start = errors[0] - 1 if errors[0] > 0 and "In function" in lines[errors[0] - 1] else errors[0]
    shown: list[str] = []
    seen: set[str] = set()
    for ln in lines[start:]:
        if ln.startswith("make") or COMPILE.search(ln):
            continue
        located = LOCATED.match(ln)
        where = located.group(0) if located else None  # a compiler's file:line:col: error (not the linker's)
        if where is not None and where in seen:  # the same error from the image's compiler (make -j): shown once
            if shown and "In function" in shown[-1]:
                shown.pop()
            break
        if where is not None:
            seen.add(where)
        shown.append(ln)
    shown = shown[:ERROR_LINES]
    upgrade = explain(lines)  # a law written against an earlier interface: what changed, and what to write instead
    if upgrade is not None:
        return f"the law in {law} does not compile: {upgrade}\nthe compiler's first error:\n" + "\n".join(shown)
    return f"the law in {law} does not compile:\n" + "\n".join(shown)


def use(law: Path) -> int:
    """Build the law and point this process (and its children) at the build; 0, or 2 after a one-line refusal."""
    try:
        out = build(law)
    except LawBuildError as exc:
        print(f"bench: --law {law}: {exc}", file=sys.stderr)
        return 2
    os.environ["BENCH_BUILD_DIR"] = str(out)
    os.environ["BENCH_LAW"] = ",".join(law_names_of(law))  # a run that selects none of them is refused
    return 0


def main(argv: list[str]) -> int:
    """`python -m bench.law DIR [GOAL...]`: what `make LAW=DIR [mcu]` runs (the Makefile hands a law build to
    this), so that make and `bench ... --law DIR` build into the one folder."""
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: python -m bench.law DIR [law|mcu ...]\n\n" + HELP, file=sys.stderr)
        return 0 if argv else 2
    goals = tuple(argv[1:])
    wrong = [g for g in goals if g not in ("law", "mcu")]
    if wrong:
        print(f"bench: make LAW=DIR {wrong[0]}: a law builds the goals law (default) and mcu only", file=sys.stderr)
        return 2
    try:
        out = build(Path(argv[0]), goals=goals)
    except LawBuildError as exc:
        print(f"bench: LAW={argv[0]}: {exc}", file=sys.stderr)
        return 2
    print(f"bench: law {law_name(Path(argv[0]))} built in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
