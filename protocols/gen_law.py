"""Law folders merged into the drive's EDS: the papers' laws always (gen_od.py), a user's on top
(protocols/gen_od.py --law DIR --out OUTDIR).

A law is a folder: its C files and headers and ONE EDS fragment, law.eds, holding exactly one record
(ObjectType=0x9) in CiA 306 syntax ([2400], [2400sub0], [2400sub1], ... with DataType/AccessType/
DefaultValue/LowLimit/HighLimit), whose section names the law in its key CurrentLaws=<name> (a lower-case
C identifier; several laws that share the record: CurrentLaws=<a>,<b>). A paper's law and a user's differ
only in where their folder lives, and so in the index range of their record: the papers' folders
(firmware_shim/laws/*/, BENCH_LAWS 0x2500 .. 0x25FF) are merged into every build, in the order of their
records' indices; a user's folder (USER_LAWS 0x2400 .. 0x24FF) after them. The merge is text-level: the
record's sections are appended to drive.eds (laid out as every EDS reader takes them: portable), listed in
[ManufacturerObjects] (SupportedObjects counted up), and the names appended to Controller.controller's
ValueNames (HighLimit raised); its DefaultLaw key names the law the drive starts with (DefaultValue, once every
folder is merged). Every refusal is one
line naming the fragment, the section and what is wrong (LawError). Plain python with `canopen`, nothing
of the bench (as gen_od.py).
"""

from __future__ import annotations

import configparser
import logging
import re
import tempfile
from collections.abc import Collection
from pathlib import Path

import canopen
import eds_reader  # protocols/: gen_od.py, which imports this module, puts its folder on sys.path

USER_LAW_FIRST, USER_LAW_LAST = 0x2400, 0x24FF  # the index range of user laws' records
USER_LAWS = range(USER_LAW_FIRST, USER_LAW_LAST + 1)
BENCH_LAWS = range(0x2500, 0x2600)  # the papers' law folders, shipped with the bench
LAWS_DIR = Path(__file__).resolve().parents[1] / "firmware_shim" / "laws"  # the papers' law folders
LAW_ENTRY = "2200sub1"  # Controller.controller: its ValueNames name the laws
FRAGMENT = "law.eds"
LAW_NAME = re.compile(r"[a-z_][a-z0-9_]*\Z")
SECTION = re.compile(r"([0-9A-Fa-f]{4})(?:sub([0-9A-Fa-f]{1,2}))?\Z", re.IGNORECASE)


class LawError(ValueError):
    """A law folder the generator refuses: one line, naming the fragment file and the section."""


def _parse(text: str, what: str) -> configparser.ConfigParser:
    try:
        return eds_reader.parse_text(text, what)
    except eds_reader.EdsError as exc:
        raise LawError(str(exc).replace(f"{what}: ", f"{what}: not an EDS fragment: ", 1)) from None


def _record(frag: Path, raw: configparser.ConfigParser) -> tuple[str, int]:
    """The fragment's one record: its section name and index."""
    tops: list[str] = []
    for sec in raw.sections():
        m = SECTION.match(sec)
        if m is None:
            raise LawError(f"{frag} [{sec}]: not an object section (a fragment holds its record's sections only)")
        if m.group(2) is None:
            tops.append(sec)
    if not tops:
        raise LawError(f"{frag}: no record section (e.g. [2400] with ObjectType=0x9)")
    if len(tops) > 1:
        raise LawError(f"{frag} [{tops[1]}]: more than one object ({', '.join(tops)}); a law has exactly one record")
    top = tops[0]
    index = int(top, 16)
    for sec in raw.sections():
        if int(SECTION.match(sec).group(1), 16) != index:  # type: ignore[union-attr]
            raise LawError(f"{frag} [{sec}]: a sub-entry of another object than [{top}]")
    if int(raw.get(top, "ObjectType", fallback="0"), 0) != 0x9:
        raise LawError(f"{frag} [{top}]: ObjectType must be 0x9 (a record)")
    return top, index


def _check_index(frag: Path, top: str, index: int, text: str, base: configparser.ConfigParser, indices: range) -> None:
    if any(int(m.group(1), 16) == index for m in map(SECTION.match, base.sections()) if m):
        owner = re.search(rf"^\[{index:04X}\]\n{PROVENANCE} (\S+):", text, re.MULTILINE | re.IGNORECASE)
        by = f" (by the law folder {owner.group(1)})" if owner else ""
        raise LawError(f"{frag} [{top}]: index 0x{index:04X} already used in drive.eds{by}")
    if index not in indices:
        whose = "user laws" if indices == USER_LAWS else "the papers' laws (firmware_shim/laws/)"
        raise LawError(
            f"{frag} [{top}]: index 0x{index:04X} outside 0x{indices[0]:04X}..0x{indices[-1]:04X} "
            f"(the range reserved for {whose})"
        )


def _law_names(frag: Path, raw: configparser.ConfigParser, top: str, existing: list[str]) -> list[str]:
    if not raw.has_option(top, "CurrentLaws"):
        raise LawError(f"{frag} [{top}]: no CurrentLaws=<law name> key (the value of Controller.controller)")
    names = [n.strip() for n in raw.get(top, "CurrentLaws").split(",")]
    for name in names:
        if not LAW_NAME.match(name):
            raise LawError(
                f"{frag} [{top}]: CurrentLaws={name}: not a lower-case C identifier (laws sharing the record: "
                "CurrentLaws=<a>,<b>)"
            )
        if names.count(name) > 1:
            raise LawError(f"{frag} [{top}]: CurrentLaws={name}: named twice")
        if name in existing:
            raise LawError(f"{frag} [{top}]: CurrentLaws={name}: already a value of Controller.controller")
    return names


def _check_types(frag: Path, raw: configparser.ConfigParser, top: str, supported: Collection[int]) -> None:
    for sec in raw.sections():
        if sec == top:
            continue
        if not raw.has_option(sec, "DataType"):
            raise LawError(f"{frag} [{sec}]: no DataType key (e.g. DataType=0x0008 for REAL32)")
        given = raw.get(sec, "DataType").strip()
        try:
            dt = int(given, 0)
        except ValueError:
            names = ", ".join(f"0x{t:04X} {_type_name(t)}" for t in sorted(supported))
            raise LawError(
                f"{frag} [{sec}]: DataType={given}: not a number as CiA 306 writes it, a hex code with 0x: {names}"
            ) from None
        if dt not in supported:
            names = ", ".join(sorted(_type_name(t) for t in supported))
            raise LawError(f"{frag} [{sec}]: DataType 0x{dt:04X} not supported (a law's record holds {names})")


ACCESS = ("ro", "rw", "rww", "rwr", "const")  # parameters rw, status ro
REAL32 = 0x0008


def _number(frag: Path, sec: str, key: str, text: str, dt: int) -> float:
    try:
        return float(text) if dt == REAL32 else int(text, 0)
    except ValueError:
        kind = "a number" if dt == REAL32 else "an integer"
        raise LawError(f"{frag} [{sec}]: {key}={text}: not {kind}") from None


def _check_values(frag: Path, raw: configparser.ConfigParser, top: str) -> None:
    """What canopen reads without a word (a default that is not a number becomes none) refused here."""
    seen: dict[str, str] = {}
    for sec in (s for s in raw.sections() if s != top):
        name = raw.get(sec, "ParameterName", fallback="").strip()
        if not name:
            raise LawError(f"{frag} [{sec}]: no ParameterName")
        ident = re.sub(r"[^0-9a-z]+", "_", name.lower()).strip("_")
        if ident in seen:
            raise LawError(f"{frag} [{sec}]: ParameterName {name!r} gives the same C name as [{seen[ident]}]")
        seen[ident] = sec
        access = raw.get(sec, "AccessType", fallback="").strip().lower()
        if access not in ACCESS:
            raise LawError(f"{frag} [{sec}]: AccessType={access}: one of {', '.join(ACCESS)}")
        dt = int(raw.get(sec, "DataType"), 0)
        value = {
            k: _number(frag, sec, k, raw.get(sec, k), dt)
            for k in ("DefaultValue", "LowLimit", "HighLimit")
            if raw.has_option(sec, k)
        }
        if ("LowLimit" in value) != ("HighLimit" in value):
            raise LawError(f"{frag} [{sec}]: give both LowLimit and HighLimit or neither")
        if (
            "LowLimit" in value
            and not value["LowLimit"] <= value.get("DefaultValue", value["LowLimit"]) <= value["HighLimit"]
        ):
            raise LawError(f"{frag} [{sec}]: DefaultValue outside LowLimit..HighLimit (or LowLimit > HighLimit)")


def _ident(name: str) -> str:
    """A name as the generator makes C of it (gen_od.c_ident, lower case): struct and enum names."""
    return re.sub(r"[^0-9A-Za-z]+", "_", name).strip("_").lower()


WRITABLE = ("rw", "rww", "rwr", "wo")
GENERATOR_TYPES = ("comm", "mfr", "ram")  # gen_od.py's own struct names beside the records'
RATIO_SUFFIX = "_ratio"  # the scenario's [controller] ratio keys (bench/scenario/settings.py RATIOS)
MANUFACTURER = range(0x2000, 0x6000)


def _check_names(frag: Path, raw: configparser.ConfigParser, top: str, base: configparser.ConfigParser) -> None:
    """Names the generated C or the scenario keys would take twice: the record's name (its C type
    od_drive_<name>_t), a parameter's name (a scenario key [controller].<name>) and the name of an entry
    with ValueNames (its enum OD_DRIVE_<NAME>_<VALUE>) against drive.eds's own."""
    rec = raw.get(top, "ParameterName", fallback="").strip()
    if not rec:
        raise LawError(f"{frag} [{top}]: no ParameterName (the record's name)")
    taken_rec: dict[str, str] = {}
    taken_par: dict[str, str] = {}
    taken_enum: dict[str, str] = {}
    for sec in base.sections():
        m = SECTION.match(sec)
        if m is None or not base.has_option(sec, "ParameterName"):
            continue
        name = base.get(sec, "ParameterName").strip()
        if m.group(2) is None:
            taken_rec.setdefault(_ident(name), sec)
            continue
        if int(m.group(1), 16) in MANUFACTURER and base.get(sec, "AccessType", fallback="").strip().lower() in WRITABLE:
            taken_par.setdefault(name, sec)
        if base.has_option(sec, "ValueNames"):
            taken_enum.setdefault(_ident(name), sec)
    for own in GENERATOR_TYPES:  # the generator's own types: od_drive_comm_t, od_drive_mfr_t, od_drive_ram_t
        taken_rec.setdefault(own, f"the generator's od_drive_{own}_t")
    if _ident(rec) in taken_rec:
        where = taken_rec[_ident(rec)]
        raise LawError(
            f"{frag} [{top}]: ParameterName={rec}: {where if ' ' in where else f'drive.eds [{where}]'} has that name "
            f"(the generated C type od_drive_{_ident(rec)}_t would be defined twice)"
        )
    for sec in (x for x in raw.sections() if x != top):
        name = raw.get(sec, "ParameterName", fallback="").strip()
        access = raw.get(sec, "AccessType", fallback="").strip().lower()
        if access in WRITABLE and name in taken_par:
            raise LawError(
                f"{frag} [{sec}]: ParameterName={name}: the name of a parameter of the drive's own "
                f"(drive.eds [{taken_par[name]}]); a law's parameters are scenario keys controller.<name>, kept "
                "apart from every name the drive's parameters use: rename it"
            )
        if access in WRITABLE and name.endswith(RATIO_SUFFIX):
            raise LawError(
                f"{frag} [{sec}]: ParameterName={name}: controller.<name>{RATIO_SUFFIX} keys are the bench's "
                "model-mismatch ratios (L_hat_ratio, R_hat_ratio, ...): rename it"
            )
        if raw.has_option(sec, "ValueNames") and _ident(name) in taken_enum:
            raise LawError(
                f"{frag} [{sec}]: ParameterName={name} with ValueNames: drive.eds [{taken_enum[_ident(name)]}] "
                f"has an entry of that name with ValueNames (the enum OD_DRIVE_{_ident(name).upper()}_* "
                "would be defined twice): rename it"
            )


def _type_name(dt: int) -> str:
    from canopen.objectdictionary import datatypes

    return next((k for k, v in vars(datatypes).items() if v == dt and k.isupper()), f"0x{dt:04X}")


def _set_key(text: str, section: str, key: str, value: str) -> str:
    """`key=value` in `section` of an EDS text (replaced, or added at the section's end)."""
    m = re.search(rf"^\[{re.escape(section)}\][^\n]*\n(.*?)(?=^\[|\Z)", text, re.MULTILINE | re.DOTALL)
    if m is None:
        raise LawError(f"drive.eds: no [{section}] section")
    body = m.group(1)
    line = re.compile(rf"^{re.escape(key)}\s*=.*$", re.MULTILINE)
    new = line.sub(f"{key}={value}", body, count=1) if line.search(body) else body.rstrip("\n") + f"\n{key}={value}\n\n"
    return text[: m.start(1)] + new + text[m.end(1) :]


PROVENANCE = "; law folder"  # the comment naming the folder a merged record came from
PROSE = ("Description", "Source", "Denotation")  # keys whose values are words for a person, read by no program
SPELLED = ((">=", " is at least "), ("<=", " is at most "), ("!=", " is not "), ("==", " is "), ("=", " is "))
HEADER = re.compile(r"\[([^\]]*)\](.*)\Z")


def portable(text: str, what: str) -> str:
    """An EDS text in the layout every EDS reader takes (CiA 306's INI syntax as the strictest reader has it:
    canopen-monitor 4.1.0 splits the file at its blank lines, takes a block's first line for its [section] and
    every other line but a ';' comment for key=value at each '='). A section is one block: its header alone on its
    line first, a comment directly above a header moved under it, no blank line inside, one between sections;
    comments start with ';'; a value continued on an indented line joined into one; `key=value` without blanks
    around the first '='; a '=' inside a prose value (PROSE) spelled out in words (SPELLED), anywhere else
    refused (LawError naming `what`, the section and the key). What configparser reads (python canopen, Lely's
    dcf-tools) is unchanged but for those words."""
    blocks: list[list[str]] = []
    waiting: list[str] = []  # comments since the last blank or key line: a header right after them takes them
    keyed = False  # the last line was a key's (an indented line after it continues its value)
    for raw in text.splitlines():
        line = raw.strip()
        head = HEADER.match(line)
        if head is not None:
            rest = head.group(2).strip()
            rest = rest if not rest or rest.startswith(";") else f"; {rest.lstrip('#').strip()}"
            blocks.append([f"[{head.group(1).strip()}]", *waiting, *([rest] if rest else [])])
            waiting, keyed = [], False
        elif line.startswith((";", "#")):
            waiting.append(line if line.startswith(";") else f"; {line.lstrip('#').strip()}")
        elif not line:
            if blocks:  # comments a blank line follows head no section: they stay where they stand
                blocks[-1] += waiting
                waiting = []
        elif not blocks:
            raise LawError(f"{what}: {line}: a key before any [section]")
        elif keyed and not waiting and raw[:1].isspace():
            blocks[-1][-1] += f" {line}"  # configparser's continuation line
        else:
            blocks[-1] += waiting
            blocks[-1].append(line)
            waiting, keyed = [], True
    if blocks:
        blocks[-1] += waiting
    return "\n\n".join("\n".join(_spelled(ln, what, b[0]) for ln in b) for b in blocks) + "\n"


def _spelled(line: str, what: str, section: str) -> str:
    if line.startswith(("[", ";")):
        return line
    key, _, value = (part.strip() for part in line.partition("="))
    if "=" in value:
        if key.lower() not in (k.lower() for k in PROSE):
            raise LawError(
                f"{what} {section}: {key}={value}: a '=' in the value (EDS readers such as canopen-monitor take "
                "every '=' of a line for the key's end): only prose keys may hold one"
            )
        for sign, words in SPELLED:
            value = value.replace(sign, words)
        value = re.sub(r" {2,}", " ", value)
    return f"{key}={value}"


def merge_text(
    text: str, law_dir: Path, supported: Collection[int], indices: range = USER_LAWS
) -> tuple[list[str], int, str]:
    """(law names, record index, the drive's EDS text with the folder merged), or LawError naming what is wrong."""
    frag = law_dir / FRAGMENT
    if not frag.is_file():
        raise LawError(f"{frag}: missing (a law folder holds its C files and one EDS fragment, {FRAGMENT})")
    ftext = frag.read_text()
    raw = _parse(ftext, str(frag))
    top, index = _record(frag, raw)
    base = _parse(text, "drive.eds")
    _check_index(frag, top, index, text, base, indices)
    names = [n.strip() for n in base.get(LAW_ENTRY, "ValueNames").split(",")]
    new = _law_names(frag, raw, top, names)
    _check_types(frag, raw, top, supported)
    _check_values(frag, raw, top)
    _check_names(frag, raw, top, base)
    count = int(base.get("ManufacturerObjects", "SupportedObjects"), 0)
    text = _set_key(text, "ManufacturerObjects", "SupportedObjects", str(count + 1))
    text = _set_key(text, "ManufacturerObjects", str(count + 1), f"0x{index:04X}")
    text = _set_key(text, LAW_ENTRY, "ValueNames", ",".join([*names, *new]))
    if base.has_option(LAW_ENTRY, "HighLimit"):
        text = _set_key(text, LAW_ENTRY, "HighLimit", str(len(names) + len(new) - 1))
    # the folder's name as a comment under its record's header (above it, canopen-monitor refuses the file: portable)
    ftext = portable(ftext, str(frag)).replace(
        f"[{top}]\n", f"[{top}]\n{PROVENANCE} {law_dir.name}: {', '.join(new)}\n", 1
    )
    text = text.rstrip("\n") + "\n\n" + ftext
    _canopen_check(frag, top, text)
    return new, index, text


def bench_law_dirs(laws_dir: Path = LAWS_DIR) -> list[Path]:
    """The papers' law folders (every folder of firmware_shim/laws/ with a law.eds), in their records' index order."""
    found: list[tuple[int, Path]] = []
    for d in sorted(p for p in laws_dir.iterdir() if (p / FRAGMENT).is_file()):
        frag = d / FRAGMENT
        found.append((_record(frag, _parse(frag.read_text(), str(frag)))[1], d))
    return [d for _, d in sorted(found)]


def merge_all(drive_eds: Path, user_law: Path | None, supported: Collection[int], laws_dir: Path = LAWS_DIR) -> str:
    """drive.eds with the papers' law folders (those of laws_dir) and then the user's (None: none) merged, its
    default law set."""
    text = drive_eds.read_text()
    for d in bench_law_dirs(laws_dir):
        text = merge_text(text, d, supported, BENCH_LAWS)[2]
    if user_law is not None:
        text = merge_text(text, user_law, supported, USER_LAWS)[2]
    return _default_law(text)


def _default_law(text: str) -> str:
    """Controller.controller's DefaultValue: the value its DefaultLaw key names (no key: as drive.eds says); a
    DefaultLaw that names no merged law is refused (the drive would start in open loop without a word)."""
    base = _parse(text, "drive.eds")
    wanted = base.get(LAW_ENTRY, "DefaultLaw", fallback="").strip()
    names = [n.strip() for n in base.get(LAW_ENTRY, "ValueNames").split(",")]
    if not wanted:
        return text
    if wanted not in names:
        raise LawError(f"drive.eds [{LAW_ENTRY}]: DefaultLaw={wanted}: not one of the merged laws ({', '.join(names)})")
    return _set_key(text, LAW_ENTRY, "DefaultValue", str(names.index(wanted)))


def _canopen_check(frag: Path, top: str, text: str) -> None:
    """The merged EDS read by `canopen` (as the bench and the generator read it): a warning or an error
    (drive.eds alone has none: gen_od.py refuses it) is the fragment's."""
    handler = eds_reader.Collect()
    logging.getLogger("canopen").addHandler(handler)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "drive.eds"
            path.write_text(text)
            canopen.import_od(str(path))
    except Exception as exc:  # canopen raises what its parsers raise (ValueError, KeyError, ...)
        sec = _section_in(str(exc), top)
        tb = exc.__traceback__
        while tb is not None:  # the section canopen was reading (its eds.py keeps it in `section`)
            name = tb.tb_frame.f_locals.get("section")
            if isinstance(name, str) and name.upper().startswith(top.upper()):
                sec = name
            tb = tb.tb_next
        raise LawError(f"{frag} [{sec}]: canopen refused it: {exc}") from None
    finally:
        logging.getLogger("canopen").removeHandler(handler)
    if handler.messages:
        first = handler.messages[0]
        raise LawError(f"{frag} [{_section_in(first, top)}]: canopen warned: {first}")


def _section_in(message: str, top: str) -> str:
    """The sub-entry a canopen message names (0x2400:01 / 2400sub1), else the record's section."""
    m = re.search(rf"(?:0x)?{top}(?:sub|:)([0-9A-Fa-f]{{1,2}})", message, re.IGNORECASE)
    return f"{top}sub{int(m.group(1), 16):X}" if m else top
