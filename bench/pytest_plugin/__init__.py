"""The bench's pytest plugin (entry point pytest11 `pmsm_hil`: installing pmsm-hil-bench enables it).

    def test_matched_deadbeat_settles_in_two_periods(hil_run):
        run = hil_run("scenarios/you2019_step.toml", {"scenario.periods": 60})
        run.expect_status("ok").expect_settles_within(2, signal="iq").expect_overshoot_below(1.0)
        assert abs(run["iq_A"][-1] - 1.0) < 0.01

Fixtures: `hil_run` (a callable: one `bench run` per call, a direct one in the test's process, its result a HilRun;
fixture.py says its arguments)
and `hil_bus` (the session's bus). Options (and ini keys): --hil-bus (hil_bus; direct, vcan0, can0 ...; default
direct), --hil-law=DIR (hil_law; a user's current law, built at the session's start as `bench run --law`
does), --hil-out=DIR (hil_out; the run folders, default <rootdir>/hil-runs), --hil-isolate (hil_isolate; every run a
process of its own); the DIR options with "=": pytest
takes a separate DIR for a test path when it looks for its rootdir. A bus that is not there, the VM
fallback not ready, a law that does not build: pytest stops with "ERROR: ..." before any test. A failing
test's report names each run's folder, bus log and Rerun recording; its key figures are JUnit properties.

This module is imported by every pytest session where the package is installed: it imports nothing of the
bench at its top, only in the hooks and fixtures that need it.
"""

from __future__ import annotations

from collections.abc import Generator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from bench.pytest_plugin.state import RUN_TEXTS, RUN_VIEWS, SETTINGS, LaterView, Settings

if TYPE_CHECKING:
    from bench.pytest_plugin.fixture import HilRunner

__all__ = ["HilRun", "Step", "load_run"]
VIEWS = ("failed", "all")  # --hil-view


def __getattr__(name: str) -> Any:
    """HilRun, Step and load_run on demand (the plugin stays cheap to load)."""
    if name in ("HilRun", "load_run"):
        import bench.result as result

        return getattr(result, name)
    if name == "Step":
        from bench.result.steps import Step

        return Step
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("pmsm-hil", "PMSM HIL bench (bench.pytest_plugin; the hil_run fixture)")
    options = (
        (
            "bus",
            "BUS",
            "the bus of hil_run's runs: direct (in-process, default), vcan0 (the VM supplies it on hosts without "
            "kernel CAN), can0, ... (bench run --bus); checked at the session's start",
        ),
        (
            "law",
            "DIR",
            "a user's current-law folder (C files and law.eds), built at the session's start and used by every run "
            "(bench run --law); the scenarios must select it",
        ),
        ("out", "DIR", "where the run folders go, one sub-folder per test (default: hil-runs under the rootdir)"),
    )
    group.addoption(
        "--hil-require",
        dest="hil_require",
        action="store_true",
        default=None,
        help="a test marked @pytest.mark.hil(bus=..., drive=...) whose bus or drive this host lacks errors at its "
        "setup, naming the missing piece, instead of being skipped (for the CI job that must run them)",
    )
    parser.addini("hil_require", "as --hil-require", type="bool", default=False)
    group.addoption(
        "--hil-isolate",
        dest="hil_isolate",
        action="store_true",
        default=None,
        help="every hil_run a `bench run` process of its own; without it a direct run (no law= of the call, no "
        "timeout=) runs in the test's process, ~100x cheaper, and a crash of the C library ends that process (an "
        "xdist worker: pytest reports it and goes on)",
    )
    parser.addini("hil_isolate", "as --hil-isolate", type="bool", default=False)
    group.addoption(
        "--hil-view",
        dest="hil_view",
        choices=VIEWS,
        default=None,
        help="the run.rrd recording and SVG plots of a direct run in the test's process: 'failed' (default) draws "
        "them only for a failing test's runs, when it fails (a passing test's run costs ~10x less); 'all' draws them "
        "for every run. A run in a process of its own always has them",
    )
    parser.addini("hil_view", "as --hil-view", default="failed")
    # --hil-law=DIR rather than --hil-law DIR: pytest looks for its rootdir before it loads plugins, and takes a
    # folder after an option it does not know yet for a test path (pytest-dev/pytest#8846)
    eq = "; write --hil-{name}=DIR (pytest would take a separate DIR for a test path when it looks for its rootdir)"
    for name, metavar, text in options:
        note = eq.format(name=name) if metavar == "DIR" else ""
        group.addoption(f"--hil-{name}", dest=f"hil_{name}", default=None, metavar=metavar, help=text + note)
        parser.addini(f"hil_{name}", f"as --hil-{name} (the command line wins); relative to the ini file", default="")


def _path(config: pytest.Config, name: str) -> Path | None:
    """An option's folder: the command line's relative to the invocation folder, the ini's to the ini file's."""
    given = config.getoption(f"hil_{name}")
    if given:
        return (config.invocation_params.dir / Path(given).expanduser()).absolute()
    ini = str(config.getini(f"hil_{name}") or "")
    if ini:
        base = config.inipath.parent if config.inipath else config.rootpath
        return (base / Path(ini).expanduser()).absolute()
    return None


def pytest_configure(config: pytest.Config) -> None:
    cli, ini = config.getoption("hil_bus"), str(config.getini("hil_bus") or "")
    out = _path(config, "out") or config.rootpath / "hil-runs"
    option = "--hil-bus" if cli or not ini else f"{config.inipath or 'the ini file'}: hil_bus"
    require = bool(config.getoption("hil_require") or config.getini("hil_require"))
    isolate = bool(config.getoption("hil_isolate") or config.getini("hil_isolate"))
    view = str(config.getoption("hil_view") or config.getini("hil_view") or "failed")
    if view not in VIEWS:
        raise pytest.UsageError(f"{config.inipath or 'the ini file'}: hil_view = {view!r}: one of {', '.join(VIEWS)}")
    config.stash[SETTINGS] = Settings(
        bus=cli or ini or "direct",
        law=_path(config, "law"),
        out=out,
        bus_option=option,
        require=require,
        isolate=isolate,
        view=view,
    )
    config.addinivalue_line(
        "markers",
        "hil(bus=None, law=None, motor=None, drive=None): a HIL test's needs: its runs' bus (vcan0, can0, ...), law "
        "folder and motor (a motor folder, or an FMU mapping as a dict) as hil_run's defaults, drive='mcu' for the "
        "Cortex-M4F image; skipped naming what this host lacks (no kernel CAN nor the CAN box's pieces, no "
        "can-utils, no QEMU for the image) unless --hil-require",
    )
    from bench.pytest_plugin.box import BoxHooks
    from bench.pytest_plugin.cancel import CANCEL, Cancel

    cancel = config.stash[CANCEL] = Cancel(config)
    config.pluginmanager.register(cancel, "pmsm_hil_cancel")
    config.pluginmanager.register(BoxHooks(config, cancel), "pmsm_hil_box")


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session: pytest.Session) -> None:
    """The bus is there (or the VM can supply it) and the law builds, before any test: else a usage error."""
    config = session.config
    settings = config.stash[SETTINGS]
    from bench.pytest_plugin.checks import bus_problem  # none for the direct bus

    problem = settings.bus_problems[settings.bus] = bus_problem(settings.bus, settings.bus_option)
    if problem is not None:
        raise pytest.UsageError(problem)
    from bench.pytest_plugin import box

    box.start(config)  # one CAN box per session, shared by the xdist workers
    if settings.law is not None:  # an xdist worker too: the controller's build, found current (no compile)
        from bench.pytest_plugin.checks import restore, use_law

        before = use_law(settings, settings.law)
        config.add_cleanup(lambda: restore(before))


MARKER_KEYS = ("bus", "law", "motor", "drive")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """A test marked hil(bus=..., drive=...) whose bus or drive this host cannot give: skipped, the missing piece
    named (failed under --hil-require). A law that does not build is the test's failure, not a skip."""
    marker = item.get_closest_marker("hil")
    if marker is None:
        return
    settings = item.config.stash[SETTINGS]
    wrong = [k for k in marker.kwargs if k not in MARKER_KEYS] or (["positional arguments"] if marker.args else [])
    if wrong:
        pytest.fail(f"@pytest.mark.hil: {wrong[0]!r} is not one of its arguments ({', '.join(MARKER_KEYS)})", False)
    bus, drive = marker.kwargs.get("bus") or settings.bus, marker.kwargs.get("drive") or "node"
    if drive not in ("node", "mcu"):
        pytest.fail(f"@pytest.mark.hil: drive={drive!r}: expected 'node' or 'mcu'", False)
    key = f"{bus} {drive}"
    if key not in settings.bus_problems:
        from bench.pytest_plugin.checks import bus_problem

        named = "hil(bus=...)" if marker.kwargs.get("bus") else settings.bus_option  # where the bus came from
        settings.bus_problems[key] = bus_problem(bus, named, drive)
    problem = settings.bus_problems[key]
    if problem is not None:
        if settings.require:
            pytest.fail(f"--hil-require: {problem}", pytrace=False)
        pytest.skip(problem)


@pytest.fixture(scope="session")
def hil_bus(pytestconfig: pytest.Config) -> str:
    """The session's bus (--hil-bus, ini hil_bus; default direct)."""
    return pytestconfig.stash[SETTINGS].bus


@pytest.fixture
def hil_run(request: pytest.FixtureRequest) -> HilRunner:
    """Runs a scenario: hil_run(scenario, overrides=None, *, bus=None, law=None, motor=None, name=None, faults=None,
    events=None, timeout=None, extra_args=()) returns the run's HilRun (summary, steps, status, exit code, traces,
    folder); bench/pytest_plugin/fixture.py (HilRunner) says more."""
    from bench.pytest_plugin.fixture import HilRunner

    return HilRunner(request, request.config.stash[SETTINGS])


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
    """A failing test that ran scenarios: a report section naming each run's folder, bus log and recording."""
    report = yield
    from bench.pytest_plugin.box import BOX

    log = item.config.stash.get(BOX, None)
    if log is not None and log.pending:  # an xdist worker's box lines, for the controller to print
        report.hil_box_lines, log.pending = log.pending, []
    texts = item.stash.get(RUN_TEXTS, None)
    views = item.stash.get(RUN_VIEWS, None)
    if views and texts and report.failed:  # --hil-view=failed: the runs' recording and plots, now
        _draw(views, texts)
    if views and report.when == "teardown":
        for later in views:
            later.view.release()  # a passing test's kept chunks go
        views.clear()
    if texts and report.failed:
        title = "HIL run" if len(texts) == 1 else f"HIL runs ({len(texts)})"
        report.sections.append((title, "\n\n".join(texts)))
        # and as the test's stdout, which pytest's JUnit report writes (from the teardown's report) as its
        # system-out under junit_logging = system-out or all: CI servers that show no properties (GitLab) show it
        item.add_report_section("call", "stdout", f"{title}\n" + "\n\n".join(texts))
    return report


def _draw(views: list[LaterView], texts: list[str]) -> None:
    """Draw the kept runs' recording and plots, and write their report texts again to name them."""
    from dataclasses import replace

    from bench.pytest_plugin.result import report_text

    for later in views:
        try:
            files = later.view.draw(later.run.folder)
        except Exception as exc:  # noqa: BLE001 - the test's failure is the report's subject, not this
            texts[later.text] += f"\nrecording and plots: not drawn ({exc})"
            continue
        folder = later.run.folder
        run = replace(later.run, recording=folder / "run.rrd" if "run.rrd" in files else later.run.recording)
        texts[later.text] = report_text(run) + "\n" + later.reproduce
    views.clear()
