"""Issue 28 and 39: the bench as a user's CI has it. A fresh virtual environment outside the clone, `pip install`
of the repository (the C nodes built at install time; the plain install, no extras) next to the user's own pins
(pytest 8.3, numpy 1.26, pytest-xdist), then the example project examples/ci_project run by pytest with the
plugin the package enables: in direct mode with two workers (two laws in one session, a vcan test skipped on a
host without can-utils), with a broken expectation, over vcan (the CAN box on this host), and `bench
run|sweep|replay` from a folder that is not the clone. The wheel's contents are listed against the build they
must carry. Issue 52: the extras `.[view,fmu]` installed beside numpy 1.26 and pytest 8.3 in one pip command, a run
recorded (run.rrd) and an FMU built and run with them, bench doctor there."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import venv
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bench.paths import REPO

EXAMPLE = REPO / "examples" / "ci_project"
PIP_TIMEOUT_S = 1800
USER_PINS = ["pytest==8.3.5", "numpy==1.26.4", "pytest-xdist==3.8.0"]  # a firmware team's own, next to the bench
EXTRAS_PINS = ["numpy==1.26.*", "pytest==8.3.*"]  # issue 52: the extras beside a team's numpy 1.x
# what pip picks for them beside numpy 1.26: the releases of pyproject.toml's ranges that take numpy 1.x, the
# oldest each range allows (the lock's, beside numpy 2, are the repository's own set-up's)
EXTRAS_PICKED = {"rerun-sdk": "0.23.1", "fmpy": "0.3.22"}
CACHE = Path(tempfile.mkdtemp(prefix="bench-user-cache-"))


def _run(
    argv: list[str], cwd: Path, timeout: float = 1800, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """A command as a user's shell runs it: none of this suite's variables; the installed bench's working folder
    (law builds, VM jobs, EDS cache) in the test's temporary folder, not this machine's ~/.cache."""
    extra = env
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BENCH_", "PYTEST_", "VIRTUAL_ENV"))}
    env.pop("PYTHONPATH", None)
    env["BENCH_CACHE_DIR"] = str(CACHE)
    env = {**env, **(extra or {})}
    # stdin: none, as in a CI job (`rerun rrd print` waits on a terminal's)
    return subprocess.run(
        argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout
    )


@pytest.fixture(scope="module")
def user(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with the package installed from the repository, as `pip install <path>` does."""
    home = tmp_path_factory.mktemp("user")
    env_dir = home / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    pins = [*USER_PINS, str(REPO)]
    res = _run([str(env_dir / "bin" / "python"), "-m", "pip", "install", "-q", *pins], home, PIP_TIMEOUT_S)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    code = (
        "import numpy, pytest, importlib.util as u; print(numpy.__version__, pytest.__version__, u.find_spec('rerun'))"
    )
    got = _run([str(env_dir / "bin" / "python"), "-c", code], home)
    assert got.stdout.split()[:3] == ["1.26.4", "8.3.5", "None"], got.stdout + got.stderr  # the user's, no extra
    return home


def _project(user: Path, name: str) -> Path:
    """The example project, with the example law folder beside it where its test_laws.py finds it (../laws)."""
    dst = user / name / "ci_project"
    shutil.copytree(EXAMPLE, dst, ignore=shutil.ignore_patterns("__pycache__", "hil-runs", ".pytest_cache"))
    shutil.copytree(REPO / "examples" / "laws", user / name / "laws", ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def _without_candump(user: Path) -> dict[str, str]:
    """PATH of a host without can-utils (a CI image that lacks it): this one's, candump left out."""
    shim = user / "bin-without-can-utils"
    if not shim.is_dir():
        shim.mkdir()
        for d in os.environ["PATH"].split(os.pathsep):
            for exe in Path(d).glob("*") if Path(d).is_dir() else []:
                if exe.name != "candump" and not (shim / exe.name).exists():
                    (shim / exe.name).symlink_to(exe)
    return {"PATH": str(shim)}


def _pytest(
    user: Path, project: Path, *args: str, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    py = str(user / "venv" / "bin" / "python")
    return _run([py, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rA", *args], project, env=env)


def test_the_installed_package_is_not_the_clone(user: Path) -> None:
    code = "import bench.root as r, bench.paths as p; print(r.INSTALLED, r.REPO, p.binary('plant_node'))"
    res = _run([str(user / "venv" / "bin" / "python"), "-c", code], user)
    assert res.returncode == 0, res.stderr
    installed, root, plant = res.stdout.split()
    assert installed == "True" and not Path(root).is_relative_to(REPO) and Path(plant).is_relative_to(root)
    doctor = _run([str(user / "venv" / "bin" / "bench"), "doctor"], user)
    assert re.search(r"C build +\S+/bench/_root/build/bin \(installed package\)", doctor.stdout), doctor.stdout


def test_without_a_c_compiler_pip_says_which_package_to_install(tmp_path: Path) -> None:
    env = {**os.environ, "CC": "no-such-cc"}
    argv = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-w", str(tmp_path), str(REPO)]
    res = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=PIP_TIMEOUT_S)
    out = res.stdout + res.stderr
    assert res.returncode != 0 and not list(tmp_path.glob("*.whl")), out[-3000:]
    assert "`no-such-cc` is not installed" in out and "apt-get install build-essential" in out, out[-3000:]


def test_the_example_project_passes_in_direct_mode(user: Path) -> None:
    """Two workers (pytest-xdist), two laws in the session, the vcan test skipped where can-utils is missing."""
    project = _project(user, "direct")
    # --hil-view=all: every run draws its view, so the plain install's "no run.rrd" below is checked on each
    res = _pytest(user, project, "-n", "2", "--junitxml", "junit.xml", "--hil-view=all", env=_without_candump(user))
    out = res.stdout
    assert res.returncode == 0, out[-4000:] + res.stderr[-2000:]
    assert re.search(r"\b5 passed, 1 skipped\b", out), out[-2000:]
    assert re.search(r"SKIPPED \[1\] .*hil\(bus=\.\.\.\) vcan0: candump \(can-utils\) is not installed", out), out
    junit = (project / "junit.xml").read_text()
    assert 'name="hil_status" value="ok"' in junit and 'name="hil_status" value="frames_lost"' in junit
    assert 'name="hil_bus" value="direct"' in junit and 'name="hil_bench_version" value="' in junit
    assert 'name="hil_law" value="complex_vector_pi"' in junit and re.search(
        r'"hil_law_digest" value="[0-9a-f]{16}"', junit
    )
    assert len(list((project / "hil-runs").rglob("summary.json"))) == 5
    assert not list((project / "hil-runs").rglob("run.rrd"))  # the plain install: no Rerun recording


def test_a_broken_expectation_fails_with_the_measured_figure_and_the_run_folder(user: Path) -> None:
    project = _project(user, "broken")
    test = project / "test_current_loop.py"
    text = test.read_text()
    assert "run.expect_settles_within(5)" in text
    test.write_text(text.replace("run.expect_settles_within(5)", "run.expect_settles_within(2)", 1))
    res = _pytest(user, project, "--junitxml", "junit.xml", env=_without_candump(user))
    out = res.stdout
    assert res.returncode == 1 and re.search(r"\b1 failed, 4 passed, 1 skipped\b", out), out[-4000:]
    assert re.search(r"settles in 4 periods", out) and "within 2 periods" in out, out[-4000:]
    folders = [Path(m) for m in re.findall(r"Run: (\S+)", out)]
    assert folders and all((f / "summary.json").is_file() for f in folders), out[-4000:]
    assert "bus.log" in out and "traces.npy" in out
    import xml.etree.ElementTree as ET

    cases = {c.get("name"): c for c in ET.parse(project / "junit.xml").getroot().iter("testcase")}
    shown = cases["test_step_meets_the_spec"].findtext("system-out") or ""  # pytest.ini: junit_logging
    assert "HIL run" in shown and "reproduce:" in shown and str(folders[0]) in shown, shown


def test_bench_run_sweep_and_replay_outside_the_clone(user: Path) -> None:
    work = user / "work"
    work.mkdir()
    bench = str(user / "venv" / "bin" / "bench")
    scenario = str(EXAMPLE / "scenarios" / "iq_step.toml")
    run = _run([bench, "run", scenario, "--bus", "direct", "--no-viewer", "--out", "run1"], work)
    assert run.returncode == 0 and (work / "run1" / "traces.npy").is_file(), run.stdout[-2000:] + run.stderr
    # the bench's own scenario by the README's relative name, from a folder that has none (bench.scenario.bundled):
    # without the [sweep] extra, bench sweep says which extra to install and writes nothing
    own = "scenarios/you2019_step.toml"
    sweep = [bench, "sweep", own, "--grid", "controller.L_hat_ratio=0.8,1.2", "--out", "sweep1"]
    res = _run(sweep, work)
    assert res.returncode == 2 and not (work / "sweep1").exists(), res.stdout[-2000:] + res.stderr
    assert "bench sweep needs the package's [sweep] extra" in res.stderr, res.stderr
    # the line adds the extra from where the bench came (this repository's folder), the user's numpy pinned
    assert f"bin/python -m pip install '{REPO}[sweep]' numpy==1.26.4" in res.stderr, res.stderr
    replay = _run([bench, "replay", "run1/bus.log", "--no-viewer", "--out", "replay1"], work)
    assert replay.returncode == 0, replay.stdout[-2000:] + replay.stderr
    assert "no run.rrd: a Rerun recording needs the package's [view] extra" in replay.stderr, replay.stderr
    ran, replayed = np.load(work / "run1" / "traces.npy"), np.load(work / "replay1" / "traces.npy")
    assert ran.dtype.names == replayed.dtype.names
    assert all(np.array_equal(ran[n], replayed[n], equal_nan=True) for n in ran.dtype.names)


def test_the_example_project_passes_over_vcan(user: Path) -> None:
    """Over vcan0: the host's own when its kernel has CAN, else the session's CAN box."""
    project = _project(user, "vcan")
    res = _pytest(user, project, "--hil-bus", "vcan0", "--hil-require")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]
    assert re.search(r"\b6 passed\b", res.stdout), res.stdout[-2000:]
    summaries = list((project / "hil-runs").rglob("summary.json"))
    assert len(summaries) == 6 and all('"bus": "vcan0"' in s.read_text() for s in summaries)


def _expected_build() -> set[str]:
    """What `make package` leaves for a run: the node processes, the gateway, libhil.so and every tool."""
    tools = [
        p.stem for d in ("protocols/tools", "plant_rt/tools", "firmware_shim/tools") for p in (REPO / d).glob("*.c")
    ]
    names = {f"build/bin/{t}" for t in [*tools, "plant_node", "drive_node", "fault_gateway"]} | {"build/libhil.so"}
    if shutil.which("arm-none-eabi-gcc"):
        names |= {"build/mcu/drive_mcu.elf", "build/mcu/drive_mcu.bin"}
    return names


def _tracked(*folders: str) -> set[str]:
    res = subprocess.run(["git", "ls-files", *folders], cwd=REPO, capture_output=True, text=True, check=True)
    return set(res.stdout.split())


def test_the_wheel_holds_the_build_and_no_path_of_its_machine(tmp_path: Path) -> None:
    res = _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(REPO)], tmp_path)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    (wheel,) = tmp_path.glob("pmsm_hil_bench-*.whl")
    assert re.search(r"-py3-none-linux_\w+\.whl$", wheel.name), wheel.name  # compiled, no Python ABI: one per platform
    z = zipfile.ZipFile(wheel)
    names = set(z.namelist())
    root = "bench/_root/"
    built = {n[len(root) :] for n in names if n.startswith(root + "build/")}
    assert _expected_build() <= built, sorted(_expected_build() - built)
    assert not [n for n in built if n.endswith((".o", ".d", ".a"))]
    python = {p for p in _tracked("bench") if p.endswith(".py")}
    assert python <= names, sorted(python - names)
    sources = {p for p in _tracked("protocols", "plant_rt", "firmware_shim", "scenarios", "bench/direct", "Makefile")}
    needed = {p for p in sources if "/tests/" not in p and "/fuzz/" not in p and not Path(p).name.startswith(".")}
    assert {root + p for p in needed} <= names, sorted({root + p for p in needed} - names)[:10]
    entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    points = z.read(entry).decode()
    assert "bench = bench.cli:main" in points and "pmsm_hil = bench.pytest_plugin" in points
    machine = [str(REPO).encode(), b"build/setuptools"]
    leaks = [n for n in names if any(m in z.read(n) for m in machine)]
    assert not leaks, leaks


@pytest.fixture(scope="module")
def extras_user(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A fresh venv with `<repository>[view,fmu]` beside numpy 1.26 and pytest 8.3, in one pip command as a team's
    CI runs it; the versions pip picked."""
    home = tmp_path_factory.mktemp("extras")
    env_dir = home / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    py = str(env_dir / "bin" / "python")
    res = _run([py, "-m", "pip", "install", "-q", *EXTRAS_PINS, f"{REPO}[view,fmu]"], home, PIP_TIMEOUT_S)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    dists = ("numpy", "pytest", "rerun-sdk", "fmpy", "pyarrow", "matplotlib")
    code = f"import importlib.metadata as m; print(*(m.version(d) for d in {dists!r}))"
    got = _run([py, "-c", code], home)
    assert got.returncode == 0, got.stderr
    versions = dict(zip(dists, got.stdout.split(), strict=True))
    assert versions["numpy"].startswith("1.26.") and versions["pytest"].startswith("8.3."), versions  # the team's
    assert {d: versions[d] for d in EXTRAS_PICKED} == EXTRAS_PICKED, versions
    return home, versions


def test_the_extras_beside_numpy_1_26_record_a_run(extras_user: tuple[Path, dict[str, str]]) -> None:
    """`bench run` of the example project's step writes a Rerun recording with rerun-sdk 0.23.1 on numpy 1.26 (its
    pyarrow <26: 26 refuses numpy 1.x at import), which its own rerun reads back; doctor there: [view] and [fmu]
    installed, [sweep] optional, with a line that adds it from this repository and keeps numpy 1.26."""
    home, versions = extras_user
    work = home / "record"
    work.mkdir()
    bench = str(home / "venv" / "bin" / "bench")
    scenario = str(EXAMPLE / "scenarios" / "iq_step.toml")
    res = _run([bench, "run", scenario, "--bus", "direct", "--no-viewer", "--out", "run1"], work)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    out = work / "run1"
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"
    rrd = out / "run.rrd"
    assert rrd.is_file() and rrd.stat().st_size > 0, sorted(p.name for p in out.iterdir())
    printed = _run([str(home / "venv" / "bin" / "rerun"), "rrd", "print", str(rrd)], work, timeout=300)
    assert printed.returncode == 0 and "/A/iq_A" in printed.stdout, printed.stdout[-2000:] + printed.stderr[-2000:]
    doctor = _run([bench, "doctor"], work)
    text = doctor.stdout
    assert doctor.returncode == 0 and "problem(s)" not in text, text  # a missing extra is no problem
    assert re.search(rf"\[ok \] \[view\] extra +rerun-sdk {versions['rerun-sdk']}, pyarrow ", text), text
    assert re.search(rf"\[ok \] \[fmu\] extra +fmpy {versions['fmpy']}", text), text
    assert re.search(r"\[-- \] \[sweep\] extra +dask not installed", text), text
    assert f"-m pip install '{REPO}[sweep]' numpy=={versions['numpy']}" in text, text
    assert "Optional, not installed: [sweep] extra" in text, text


FMU_SCENARIO = """[scenario]
name = "fmu-step"
periods = 200

[motor]
preset = "you2019"

[motor.fmu]
file = "linear_pmsm.fmu"
inputs = { v_alpha_V = "v_alpha", v_beta_V = "v_beta" }
outputs = { i_a_A = "i_a", i_b_A = "i_b", theta_m_rad = "theta_m", omega_m_rad_s = "omega_m" }

[drive]
preset = "ideal"

[[events]]
at_period = 20
references = { iq_ref_A = 1.0 }
"""


def test_the_extras_beside_numpy_1_26_build_and_run_an_fmu(extras_user: tuple[Path, dict[str, str]]) -> None:
    """docs/YOUR_MOTOR.md section 8 with FMPy 0.3.22 on numpy 1.26: `bench motor fmu-build` of the example FMU
    (FMPy's FMI headers), then a run with it as the plant (FMPy reads and validates it): status ok, the step ran."""
    home, _ = extras_user
    work = home / "fmu"
    work.mkdir()
    bench = str(home / "venv" / "bin" / "bench")
    build = _run([bench, "motor", "fmu-build", str(REPO / "examples" / "fmu" / "linear_pmsm"), "linear_pmsm.fmu"], work)
    assert build.returncode == 0 and (work / "linear_pmsm.fmu").is_file(), build.stdout + build.stderr
    (work / "fmu_step.toml").write_text(FMU_SCENARIO)
    res = _run([bench, "run", "fmu_step.toml", "--bus", "direct", "--no-viewer", "--out", "fmu1"], work)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    assert json.loads((work / "fmu1" / "summary.json").read_text())["status"] == "ok"
    iq = np.load(work / "fmu1" / "traces.npy")["iq_A"]
    assert np.abs(iq).max() > 0.5  # the FMU plant answered the step
