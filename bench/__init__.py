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


def __getattr__(name: str) -> str:
    """`bench.__version__`, read when first asked for (tomllib and the metadata cost every `bench` command ~30 ms)."""
    if name == "__version__":
        globals()["__version__"] = version = _version()
        return version
    raise AttributeError(f"module 'bench' has no attribute {name!r}")
