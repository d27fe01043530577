"""PMSM deadbeat current control hardware-in-the-loop bench over CANopen (SocketCAN)."""

from __future__ import annotations


def _version() -> str:
    """pyproject.toml's [project] version, the one place it is written (CHANGELOG.md names what each changed): read
    there in a clone (an editable install's metadata keeps the version it was installed at), else the installed
    package's metadata, which pip wrote from it."""
    from pathlib import Path

    pyproject = Path(__file__).resolve().parent.parent / "pyproject.toml"
    if pyproject.is_file():
        import tomllib

        try:
            project = tomllib.loads(pyproject.read_text()).get("project", {})
        except (OSError, tomllib.TOMLDecodeError):
            project = {}
        if project.get("name") == "pmsm-hil-bench" and isinstance(project.get("version"), str):
            return str(project["version"])
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pmsm-hil-bench")
    except PackageNotFoundError:  # the sources on sys.path, neither a clone nor installed
        return "0+unknown"


__version__ = _version()
