"""Source conventions of the controller cores (issue 13).

1. Every equation reference names its paper: an "Eq." / "Eqs." in a comment or string of the C
   sources (firmware_shim, plant_rt, protocols, bench/direct) and of the Python under bench/ must
   be preceded by "You 2019", "Yao 2020" or "Zhao 2022", either a few words before it or at the
   start of the same comment / string (three papers share equation numbers, so a bare "Eq. 5"
   is ambiguous).  protocols/generated is made from the EDS files and is not scanned.
2. A file of a paper's law folder, firmware_shim/laws/<paper>/<paper>_<law>.c, defines only
   functions named <paper>_<law>_* (file name = function prefix), and its header only
   such functions and types <paper>_<law>_*_t.
"""

from __future__ import annotations

import io
import re
import shutil
import subprocess
import tokenize
from pathlib import Path

import pytest

from bench.eds import enum as enum_values
from bench.paths import REPO

PAPERS = ("You 2019", "Yao 2020", "Zhao 2022")
PAPER_RE = re.compile(r"\b(?:" + "|".join(map(re.escape, PAPERS)) + r")\b")
EQ_RE = re.compile(r"\bEqs?\.")
WORDS_BETWEEN = 6  # "a few words": "Yao 2020 Definition 1 (Eq. 30)", "You 2019 Eq. 2 plant with the Eq. 16 ..."
# what may stand before the paper name at the start of a comment / string: comment markers, a
# string's prefix and quotes, and the "name.c - " of a file's header comment
LEAD_RE = re.compile(r"""^\s*(?:/\*+|//+|\#+|[rRbBfFuU]{0,2}(?:"{3}|'{3}|"|'))?[\s*]*(?:[\w.-]+\.(?:c|h|py)\s+-\s+)?""")

CORE = REPO / "firmware_shim" / "core"
PAPER_FILE_RE = re.compile(r"^(you2019|yao2020|zhao2022)_[a-z0-9]+$")


# ------------------------------------------------------------------ comment / string segments
def c_segments(text: str) -> list[tuple[int, str]]:
    """(line, text) of every comment and string literal of a C file; consecutive // lines and
    adjacent string literals ("a" "b") form one segment."""
    segs: list[tuple[int, str]] = []
    i, n, line = 0, len(text), 1
    last_kind, last_end = "", -1
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            segs.append((line, text[i:j]))
            last_kind = "block"
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            if last_kind == "line" and text[last_end:i].strip() == "":
                segs[-1] = (segs[-1][0], segs[-1][1] + "\n" + text[i:j])
            else:
                segs.append((line, text[i:j]))
            last_kind = "line"
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            if c == '"':
                if last_kind == "string" and text[last_end:i].strip() == "":
                    segs[-1] = (segs[-1][0], segs[-1][1] + text[i:j])
                else:
                    segs.append((line, text[i:j]))
                last_kind = "string"
        else:
            if not c.isspace():
                last_kind = ""
            i += 1
            if c == "\n":
                line += 1
            continue
        line += text.count("\n", i, j)
        i = last_end = j
    return segs


def py_segments(text: str) -> list[tuple[int, str]]:
    """(line, text) of every comment and string of a Python file; consecutive comment lines and
    implicitly concatenated strings form one segment."""
    segs: list[tuple[int, str]] = []
    prev = None  # (kind, end row) of the last segment token
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            if prev and prev[0] == "comment" and tok.start[0] == prev[1] + 1:
                segs[-1] = (segs[-1][0], segs[-1][1] + "\n" + tok.string)
            else:
                segs.append((tok.start[0], tok.string))
            prev = ("comment", tok.end[0])
        elif tok.type == tokenize.STRING:
            if prev and prev[0] == "string":
                segs[-1] = (segs[-1][0], segs[-1][1] + tok.string)
            else:
                segs.append((tok.start[0], tok.string))
            prev = ("string", tok.end[0])
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT):
            prev = None
    return segs


def bare_equation_refs(segment: str) -> list[str]:
    """The "Eq." references of one comment/string that name no paper (with their context)."""
    starts_with_paper = PAPER_RE.match(LEAD_RE.sub("", segment)) is not None
    bad = []
    for m in EQ_RE.finditer(segment):
        if starts_with_paper:
            continue
        before = [p.end() for p in PAPER_RE.finditer(segment, 0, m.start())]
        if before and len(segment[before[-1] : m.start()].split()) <= WORDS_BETWEEN:
            continue
        bad.append(" ".join(segment[max(0, m.start() - 40) : m.end() + 12].split()))
    return bad


def scanned_files() -> list[Path]:
    c_dirs = [REPO / "firmware_shim", REPO / "plant_rt", REPO / "protocols", REPO / "bench" / "direct"]
    files = [p for d in c_dirs for p in d.rglob("*.[ch]") if "generated" not in p.relative_to(REPO).parts]
    return sorted(files) + sorted((REPO / "bench").rglob("*.py"))


def file_violations(path: Path) -> list[str]:
    text = path.read_text()
    segs = py_segments(text) if path.suffix == ".py" else c_segments(text)
    rel = path.relative_to(REPO)
    return [f"{rel}:{line}: ...{ctx}..." for line, seg in segs for ctx in bare_equation_refs(seg)]


# ------------------------------------------------------------------ the scanner itself
@pytest.mark.parametrize(
    "src",
    [
        "/* Eq. 5 */",
        "x = 1; /* Zhao 2022 */ y = 2; /* (Eq. 5) */",  # the paper of another comment does not count
        "/* the law of Yao 2020, here written in the rotor frame with the rotation of one period, Eq. 12 */",
        "/* law.c - the law of the paper, here written in the rotor frame (Eq. 12) */",
        "// ud(k) from Eq. 5\n",
        'printf("update (Eq. 28-32): %f\\n", t);',
    ],
)
def test_scanner_flags_a_bare_c_reference(src: str) -> None:
    assert len([b for _, s in c_segments(src) for b in bare_equation_refs(s)]) == 1, src


@pytest.mark.parametrize(
    "src",
    [
        "/* Zhao 2022 Eq. 5 */",
        "/* You 2019 Eq. 8/9 with the identified model gains */",
        "/* Yao 2020 Eqs. 13-15 */",
        "/* (Zhao 2022 Eq. 22/23) */",
        "/* Yao 2020 Definition 1 (Eq. 30) and Definition 2 (Eq. 31). */",
        "/* You 2019 Sec. 3.2: the estimator,\n * with the PI of Eq. 8 (q) and Eq. 9 (d),\n"
        " * and many more words before Eq. 7 */",
        "// Zhao 2022: the d axis\n// ud(k+1) = ... (Eq. 23)\n",
        "/* zhao2022_incremental.c - Zhao 2022 incremental deadbeat controller,\n * many words later:\n * Eq. 14-23 */",
        'printf("update (You 2019 Eq. 28-32): %f\\n", t);',
        'const char *s = "Yao 2020 " "Eq. 46";',
        "x = 1; /* no equation here */",
    ],
)
def test_scanner_accepts_a_named_c_reference(src: str) -> None:
    assert [b for _, s in c_segments(src) for b in bare_equation_refs(s)] == [], src


def test_scanner_on_python() -> None:
    bad = 'x = 1  # Eq. 4\nlabel = "update (Eq. 28-32)"\n"""Doc: the law\nof Eq. 22."""\n'
    good = (
        'x = 1  # Zhao 2022 Eq. 4\nlabel = ("Yao 2020 "\n         "Eq. 46-48")\n'
        '# You 2019: many words in this comment before\n# it refers to Eq. 22\n"""You 2019 law,\n\nEq. 5."""\n'
    )
    assert len([b for _, s in py_segments(bad) for b in bare_equation_refs(s)]) == 3
    assert [b for _, s in py_segments(good) for b in bare_equation_refs(s)] == []


def test_c_segments_skip_code_and_keep_lines() -> None:
    src = 'int Eq = 1;\n/* a */\nchar c = \'"\';\nconst char *s = "b\\" Eq. 5";\n// c\n// d\n'
    assert c_segments(src) == [(2, "/* a */"), (4, '"b\\" Eq. 5"'), (5, "// c\n// d")]


# ------------------------------------------------------------------ the tree
def test_every_equation_reference_names_its_paper() -> None:
    files = scanned_files()
    assert any(p.suffix == ".py" for p in files) and any(p.suffix == ".c" for p in files)
    bad = [v for p in files for v in file_violations(p)]
    assert not bad, (
        f"{len(bad)} equation reference(s) without the paper's name "
        f"({', '.join(PAPERS)}) a few words before or at the start of the comment:\n" + "\n".join(bad)
    )


def eds_segments(text: str) -> list[tuple[int, str]]:
    """(line, text) of every Description of an EDS file (what users read in a tool or the scenario errors)."""
    return [
        (i, line[len("Description=") :])
        for i, line in enumerate(text.splitlines(), 1)
        if line.startswith("Description=")
    ]


def test_every_eds_description_names_its_paper() -> None:
    bad = [
        f"{path.relative_to(REPO)}:{line}: ...{ctx}..."
        for path in sorted((REPO / "protocols" / "eds").glob("*.eds"))
        for line, seg in eds_segments(path.read_text())
        for ctx in bare_equation_refs(seg)
    ]
    assert not bad, "EDS descriptions with an equation reference that names no paper:\n" + "\n".join(bad)
    assert len(bare_equation_refs("Description=det-weighted average K1 (Eq. 28), V/A")) == 1  # the check bites


# ------------------------------------------------------------------ file name = prefix
def global_symbols(obj: Path, kinds: str) -> list[str]:
    out = subprocess.run(
        [shutil.which("nm") or "nm", "--defined-only", str(obj)], capture_output=True, text=True, check=True
    ).stdout
    return sorted(f[2] for f in (line.split() for line in out.splitlines()) if len(f) == 3 and f[1] in kinds)


def global_functions(obj: Path) -> list[str]:
    return global_symbols(obj, "T")


def law_descriptors(obj: Path) -> list[str]:
    """The global data a paper file exports: only its current laws' registry descriptors
    (firmware_shim/core/current_law.h), named current_law_<Controller.controller value name>."""
    return global_symbols(obj, "DRB")


def compile_object(src: Path, tmp: Path) -> Path:
    cc = shutil.which("cc") or shutil.which("gcc")
    assert cc, "no C compiler"
    obj = tmp / (src.stem + ".o")
    subprocess.run(
        [cc, "-std=c11", "-O2", f"-I{CORE}", f"-I{src.parent}", f"-I{REPO / 'protocols' / 'generated'}", "-c", str(src)]
        + ["-o", str(obj)],
        check=True,
        capture_output=True,
        text=True,
    )
    return obj


def misnamed_functions(src: Path, tmp: Path) -> list[str]:
    prefix = src.stem + "_"
    return [f for f in global_functions(compile_object(src, tmp)) if not f.startswith(prefix)]


def strip_function_bodies(text: str) -> str:
    """Drop the {...} bodies of inline functions (a "{" after ")"), keep struct/enum bodies."""
    out, i = [], 0
    while i < len(text):
        if text[i] == "{" and text[:i].rstrip().endswith(")"):
            depth = 0
            while i < len(text):
                depth += {"{": 1, "}": -1}.get(text[i], 0)
                i += 1
                if depth == 0:
                    break
            out.append(";")
            continue
        out.append(text[i])
        i += 1
    return "".join(out)


HEADER_NAME_RE = re.compile(r"^\s*}\s*(\w+)\s*;|^(?:static\s+inline\s+)?[\w\s*]*?\b(\w+)\s*\(", re.M)


def misnamed_header_names(header: Path) -> list[str]:
    """Types (typedef ... } name;) and functions declared or defined inline in a header that do
    not carry the file's prefix (comments and preprocessor lines ignored)."""
    text = re.sub(r"/\*.*?\*/", "", header.read_text(), flags=re.S)
    text = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))
    text = strip_function_bodies(text)
    prefix = header.stem + "_"
    names = [m[1] or m[2] for m in HEADER_NAME_RE.finditer(text)]
    return [n for n in names if not n.startswith(prefix) and n not in ("if", "for", "while", "switch", "return")]


PAPER_SOURCES = sorted(p for p in (REPO / "firmware_shim" / "laws").glob("*/*.c") if PAPER_FILE_RE.match(p.stem))


def test_paper_files_exist() -> None:
    stems = {p.stem for p in PAPER_SOURCES}
    assert {"you2019_deadbeat", "yao2020_dpcc", "zhao2022_incremental"} <= stems, stems


@pytest.mark.parametrize("src", PAPER_SOURCES, ids=[p.name for p in PAPER_SOURCES])
def test_paper_file_defines_only_its_prefix(src: Path, tmp_path: Path) -> None:
    obj = compile_object(src, tmp_path)
    laws = law_descriptors(obj)
    assert global_functions(obj) or laws, f"{src.name} defines no function and no current law"
    bad = misnamed_functions(src, tmp_path)
    assert not bad, f"{src.name} defines {bad}: its functions must be named {src.stem}_*"
    names = set(enum_values("drive", "Controller", "controller"))
    bad_laws = [n for n in laws if not (n.startswith("current_law_") and n.removeprefix("current_law_") in names)]
    assert not bad_laws, f"{src.name} exports {bad_laws}: only current_law_<Controller.controller value name>"
    header = src.with_suffix(".h")
    assert header.exists(), f"{header.name} missing"
    bad_h = misnamed_header_names(header)
    assert not bad_h, f"{header.name} declares {bad_h}: its functions and types must be named {src.stem}_*"


def test_prefix_check_catches_a_foreign_name(tmp_path: Path) -> None:
    src = tmp_path / "zhao2022_incremental.c"
    src.write_text(
        "static int helper(int x) { return x + 1; }\n"
        "int zhao2022_incremental_ok(int x) { return helper(x); }\n"
        "int bilinear_incremental_step(int x) { return x; }\n"
    )
    assert misnamed_functions(src, tmp_path) == ["bilinear_incremental_step"]
    hdr = tmp_path / "zhao2022_incremental.h"
    hdr.write_text(
        "#ifndef X_H\n#define X_H\n/* bilinear_incremental_step(x) in a comment */\n"
        "typedef struct {\n  float K1_V_A;\n} zhao2022_incremental_state_t;\n"
        "typedef struct {\n  float R;\n} bilinear_incremental_config_t;\n"
        "void zhao2022_incremental_reset(zhao2022_incremental_state_t *st);\n"
        "static inline float bilinear_incremental_law(float a,\n    float b) { return helper(a) + b; }\n"
        "static inline float zhao2022_incremental_law2(float a) {\n  if (a > 0) {\n    return g(a);\n  }\n"
        "  return 0;\n}\n#endif\n"
    )
    assert misnamed_header_names(hdr) == ["bilinear_incremental_config_t", "bilinear_incremental_law"]


# ------------------------------------------------------------------ the drive's glue knows no law
# (issue 26): drive_core, its configuration, the law interface, the node app and the port name no paper;
# they reach a law through the registry (firmware_shim/core/current_law.h) only.
GLUE = (
    *(CORE / n for n in ("drive_core.c", "drive_core.h", "drive_config.h", "current_law.h")),
    *sorted((REPO / "firmware_shim" / "shim").glob("*.[ch]")),
    *sorted((REPO / "firmware_shim" / "port").glob("*.[ch]")),
)
PAPER_NAME_RE = re.compile(r"you\s*_?2019|yao\s*_?2020|zhao\s*_?2022", re.IGNORECASE)


def papers_named(text: str) -> list[str]:
    return sorted({m.group(0) for m in PAPER_NAME_RE.finditer(text)})


def test_the_drive_glue_names_no_paper() -> None:
    named = {p.relative_to(REPO).as_posix(): papers_named(p.read_text()) for p in GLUE}
    assert len(named) > 10 and not {k: v for k, v in named.items() if v}, named


def test_paper_name_scan_finds_a_law_in_the_glue() -> None:
    assert papers_named("case DRIVE_CTRL_DEADBEAT_YOU2019: yao2020_dpcc_step(); /* Zhao 2022 */") == [
        "YOU2019",
        "Zhao 2022",
        "yao2020",
    ]
