"""Shared fixtures of the end-to-end tests (``scripts/run_scenario.py`` and its bag).

The CLI is run as a subprocess, ``[sys.executable, "scripts/run_scenario.py", ...]``, with the
repository root as the working directory, exactly as a user runs it. The packages are imported
from the colcon install tree (``. ros2_ws/install/setup.sh``).

One recorded run (``--steps 200 --seed 3``, the shipped default config) is shared by the tests
that only read its output (:func:`recorded_run`), to keep the whole suite fast.

The plug-in examples' tests (``examples/<name>``) share :func:`load_example` (the example's module
as an installed package imports it), :func:`pip_install_into` (a package pip-installed into a
directory of its own) and :func:`env_with_path` (a subprocess environment that finds it).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = "scripts/run_scenario.py"

#: Steps and seed of the shared recorded run.
RUN_STEPS = 200
RUN_SEED = 3


@dataclass
class CliResult:
    """Outcome of one CLI run."""

    args: list[str]
    returncode: int
    stdout: str
    stderr: str

    def stderr_lines(self) -> list[str]:
        """Non-empty stderr lines (a ``\\r`` progress bar counts as text on its line)."""
        return [line for line in self.stderr.split("\n") if line.strip()]


def run_cli(*args: object, timeout: float = 120.0) -> CliResult:
    """Run ``scripts/run_scenario.py`` with ``args`` (str()-converted) from the repo root.

    Without ``--mode`` the run is ``--mode inprocess`` (the CLI's default is the node graph,
    which has its own tests in ``test_graph.py``; these tests are about the CLI itself).
    """
    argv = [str(a) for a in args]
    if "--mode" not in argv:
        argv = ["--mode", "inprocess", *argv]
    proc = subprocess.run(
        [sys.executable, SCRIPT, *argv],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    return CliResult(argv, proc.returncode, proc.stdout, proc.stderr)


def run_cli_concurrently(*arg_lists: list[object], timeout: float = 120.0) -> list[CliResult]:
    """Run several CLI commands at the same time (independent runs); results in the given order."""
    procs = []
    for args in arg_lists:
        argv = [str(a) for a in args]
        procs.append((argv, subprocess.Popen([sys.executable, SCRIPT, *argv], cwd=REPO, text=True,
                                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)))
    results = []
    for argv, proc in procs:
        stdout, stderr = proc.communicate(timeout=timeout)
        results.append(CliResult(argv, proc.returncode, stdout, stderr))
    return results


def parse_summary(stdout: str) -> dict[str, int | float | str]:
    """The numbers of the CLI's step summary (``steps``, ``collisions``, ``lane_changes``, ...)."""
    out: dict[str, int | float | str] = {}
    m = re.search(r"^steps: (\d+)\s+simulated: ([0-9.]+) s", stdout, re.M)
    if m:
        out["steps"] = int(m.group(1))
        out["sim_time_s"] = float(m.group(2))
    m = re.search(r"^all vehicles: collisions: (\d+)\s+lane changes: (\d+)\s+re-entries: (\d+)\s+off-road: (\d+); "
                  r"the SUT: lane changes: (\d+) \(completed\)", stdout, re.M)
    if m:
        (out["collisions"], out["lane_changes"], out["reentries"], out["off_road"],
         out["sut_lane_changes"]) = map(int, m.groups())
    m = re.search(r"^bag: (.+?)\s+\((\d+) messages", stdout, re.M)
    if m:
        out["bag"] = m.group(1)
        out["messages"] = int(m.group(2))
    return out


@dataclass
class RecordedRun:
    """The shared recorded run: its output directory and CLI result."""

    out: Path
    result: CliResult
    steps: int
    seed: int

    @property
    def bag_dir(self) -> Path:
        return self.out / "bag"

    @property
    def mcap_path(self) -> Path:
        # BagRecorder names the file "<bag dir name>_0.mcap"
        return self.bag_dir / "bag_0.mcap"

    @property
    def summary(self) -> dict[str, int | float | str]:
        return parse_summary(self.result.stdout)


@pytest.fixture(scope="session")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> RecordedRun:
    """``run_scenario.py --mode inprocess --steps 200 --seed 3 --out DIR`` (default config)."""
    out = tmp_path_factory.mktemp("recorded") / "run"
    res = run_cli("--mode", "inprocess", "--steps", RUN_STEPS, "--seed", RUN_SEED, "--out", out, "--quiet")
    assert res.returncode == 0, f"CLI failed ({res.returncode}): {res.stderr}"
    return RecordedRun(out=out, result=res, steps=RUN_STEPS, seed=RUN_SEED)


@pytest.fixture(scope="session")
def map_source() -> Path:
    """The shipped OpenDRIVE map (installed share file)."""
    from evoscen_sim.config.scenario_config import share_path

    return share_path("maps/onramp.xodr")


@pytest.fixture(scope="session")
def cli():
    """The :func:`run_cli` helper (test modules cannot import conftest under importlib mode)."""
    return run_cli


@pytest.fixture(scope="session")
def cli_concurrently():
    """The :func:`run_cli_concurrently` helper."""
    return run_cli_concurrently


@pytest.fixture(scope="session")
def summary_of():
    """The :func:`parse_summary` helper."""
    return parse_summary


def load_door_module(name: str):
    """``scripts/<name>.py`` as a module (scripts/ on sys.path while it loads, for its _bootstrap import)."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(REPO / "scripts"))
    return module


@pytest.fixture(scope="session")
def load_door():
    """:func:`load_door_module`: a script of scripts/ as a module (test modules cannot import each other)."""
    return load_door_module


# ---------------------------------------------------------------------- plug-in packages

EXAMPLES = REPO / "examples"


def load_example_module(name: str):
    """``examples/<name>/<name>.py`` as the module ``name``, as the installed package imports it (the
    module already imported under that name, if any: the installed one, or an earlier load)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, EXAMPLES / name / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up while it runs
        spec.loader.exec_module(module)
    return sys.modules[name]


def pip_install_to_directory(source: Path, root: Path) -> Path:
    """The package at ``source`` pip-installed (no dependencies, no index, the .venv's setuptools)
    into ``root/site``, from a copy in ``root/src`` (the source tree stays clean); returns the site."""
    copy = root / "src"
    shutil.copytree(source, copy, ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    site = root / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-deps",
                    "--no-build-isolation", "--no-index", "--target", str(site), str(copy)],
                   check=True, capture_output=True, text=True, timeout=300)
    return site


def environment_with_path(site: Path) -> dict[str, str]:
    """This process's environment with ``site`` first on ``PYTHONPATH``, then this process's path."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), *(p for p in sys.path if p)])
    return env


@pytest.fixture(scope="session")
def load_example():
    """The :func:`load_example_module` helper: ``load_example("first_sut")``."""
    return load_example_module


@pytest.fixture(scope="session")
def pip_install_into(tmp_path_factory: pytest.TempPathFactory):
    """``pip_install_into(source) -> site``: :func:`pip_install_to_directory` into a fresh temporary directory."""
    return lambda source: pip_install_to_directory(Path(source), tmp_path_factory.mktemp(Path(source).name))


@pytest.fixture(scope="session")
def env_with_path():
    """The :func:`environment_with_path` helper."""
    return environment_with_path
