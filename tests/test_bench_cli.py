"""``scripts/bench.py``, ``scripts/profile_episodes.py``, ``scripts/sut_step_cost.py``,
``scripts/profile_entries.py``: bad arguments are one-line errors before anything runs.

The benchmark's figures are not asserted (shared, noisy machines); its argument checks are.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.e2e


def bench(*args: object) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "scripts/bench.py", *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.mark.parametrize("flag, value, expected", [
    ("--graph-repeats", 0, "a positive integer"), ("--graph-steps", -5, "a positive integer"),
    ("--steps", 0, "a positive integer"), ("--repeats", -1, "a positive integer"),
    ("--bag-steps", -1, "an integer >= 0 (0 = skip)")])
def test_out_of_range_counts_are_refused(flag, value, expected):
    res = bench(flag, value)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert lines == [f"error: {flag} = {value}: expected {expected}"], res.stderr
    assert "steps/s" not in res.stdout  # refused before measuring


def test_unknown_bv_driver_is_refused():
    res = bench("--bv-driver", "sumo")
    assert res.returncode == 2
    assert "--bv-driver: invalid choice: 'sumo'" in res.stderr


@pytest.mark.parametrize("value", ["single,nosuch", "0", "by_policy,33"])
def test_bad_bv_node_partitions_are_refused(value):
    res = bench("--mode", "graph", "--bv-nodes", value)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert lines == [f"error: --bv-nodes = {value!r}: expected comma-separated by_policy, single or numbers "
                     "in [1, 32]"], res.stderr
    assert "steps/s" not in res.stdout


@pytest.mark.parametrize("value", ["stale,stale"])
def test_bad_experiment_mutants_are_refused(value):
    res = bench("--experiment", "--experiment-mutants", value)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: --experiment-mutants = {value!r}: expected distinct "
                                                   "comma-separated mutant names from "), res.stderr
    assert "steps/s" not in res.stdout


@pytest.mark.parametrize("value", ["highd,highd", "rush_hour"])
def test_bad_makeups_are_refused(value):
    res = bench("--makeups", value)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert lines == [f"error: --makeups = {value!r}: expected distinct comma-separated make-ups from uniform, "
                     "highd"], res.stderr
    assert "steps/s" not in res.stdout


@pytest.mark.parametrize("flag, value", [("--experiment-episodes", 0)])
def test_out_of_range_experiment_counts_are_refused(flag, value):
    res = bench("--experiment", flag, value)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert lines == [f"error: {flag} = {value}: expected a positive integer"], res.stderr


@pytest.mark.parametrize("script, args, expected, output", [
    ("profile_episodes.py", ("--scenario", "sumo"),
     "error: --scenario 'sumo': expected one of evolving, level0, nilsson, mobil", "ms per episode"),
    ("profile_episodes.py", ("--mutants", "stale,nosuch"),
     "error: --mutants: unknown mutant 'nosuch': expected 'all' or names from ", "ms per episode"),
    ("sut_step_cost.py", ("--repeats", "0"), "error: --repeats = '0': expected an integer >= 1", "CPU us per step"),
    ("sut_step_cost.py", ("--mutants", "stale,nosuch"),
     "error: --mutants: unknown mutant 'nosuch': expected 'all' or names from ", "CPU us per step"),
    ("profile_entries.py", ("--blocks", "0"), "error: --blocks = '0': expected an integer >= 1", "tries per step"),
    ("profile_entries.py", ("--seed", "x"), "error: --seed = 'x': expected an integer >= 0", "tries per step"),
    ("profile_entries.py", ("--driver", "sumo"), "error: --driver 'sumo': expected level0 or learned",
     "tries per step"),
])
def test_profiling_scripts_bad_arguments_are_one_line(script, args, expected, output):
    # one line that starts with the expected text, status 2, and nothing measured
    res = subprocess.run([sys.executable, f"scripts/{script}", *args], cwd=REPO, capture_output=True,
                         text=True, timeout=60, check=False)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(expected), res.stderr
    assert output not in res.stdout
