"""The SUT models (nilsson, mobil, stackelberg) in both runners.

* In-process: each model drives the SUT for 3,000 steps among 20 level-0 BVs without an
  exception and without a collision involving the SUT.
* Node graph (``scripts/run_scenario.py --mode graph --sut NAME``, the SUT in its own
  process): the run completes, and its bag is byte-identical to the in-process bag of the
  same scenario (every decision of the model, made from the world table on the wire, equals
  the one made in-process). The graph runs have 3,000 steps too; the three run at once, next
  to the in-process tests.
* The SUT node with an unknown model name: a one-line error listing the valid choices.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = "scripts/run_scenario.py"
MODELS = ("nilsson", "mobil", "stackelberg")
INPROCESS_STEPS = 3000
GRAPH_STEPS = 3000
SEED = 0

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]


def scenario_config(model: str, steps: int, bv_driver: str = "level0"):
    """The default scenario with SUT ``model``; by default among level-0 traffic (predictable BVs: a SUT
    collision is then the SUT's doing); ``bv_driver="learned"`` is the shipped default."""
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"sut.model": model, "steps": steps, "seed": SEED, "bvs.driver": bv_driver})
    assert cfg.bvs.count == 20 and cfg.bvs.driver == bv_driver
    return cfg


@pytest.mark.parametrize("model", MODELS)
def test_inprocess_3000_steps_without_sut_collision(model: str) -> None:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.model_registry import get_model

    assert get_model(model, "sut").factory.__module__ == f"evoscen_sut.{model}"
    sc = build_scenario(scenario_config(model, INPROCESS_STEPS))
    sut_collisions, sut_lane_changes = [], 0
    for _ in range(INPROCESS_STEPS):
        result = sc.step()
        sut_collisions += [(result.step, pair) for pair in result.collisions if sc.sut_index in pair]
        sut_lane_changes += sum(1 for c in result.lane_changes_completed if c[0] == sc.sut_index)
    assert sc.world.step_index == INPROCESS_STEPS
    assert sut_collisions == []
    assert sc.world.v[sc.sut_index] > 0.0


@pytest.fixture(scope="module", autouse=True)
def graph_processes(tmp_path_factory: pytest.TempPathFactory):
    """One graph run of GRAPH_STEPS steps per model, all three started before this module's
    first test (they run while the in-process tests do)."""
    root = tmp_path_factory.mktemp("graph_sut")
    procs = {}
    for model in MODELS:
        out = root / model
        argv = [sys.executable, SCRIPT, "--mode", "graph", "--sut", model, "--steps", str(GRAPH_STEPS),
                "--seed", str(SEED), "--out", str(out), "--quiet"]
        procs[model] = (subprocess.Popen(argv, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE),
                        out)
    yield procs
    for proc, _ in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


@pytest.fixture(scope="module")
def graph_runs(graph_processes: dict) -> dict[str, tuple[subprocess.CompletedProcess, Path]]:
    """The outcome of the three graph runs."""
    runs = {}
    for model, (proc, out) in graph_processes.items():
        stdout, stderr = proc.communicate(timeout=240)
        runs[model] = (subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr), out)
    return runs


@pytest.mark.parametrize("model", MODELS)
def test_graph_bag_equals_inprocess_bag(model: str, graph_runs: dict, tmp_path: Path) -> None:
    from evoscen_bringup.inprocess import run_inprocess

    res, out = graph_runs[model]
    assert res.returncode == 0, f"{res.stdout}\n{res.stderr}"
    assert "Traceback" not in res.stderr, res.stderr
    assert f"steps: {GRAPH_STEPS} " in res.stdout, res.stdout
    assert "evoscen_sut=0" in res.stdout and "evoscen_sim=0" in res.stdout, res.stdout
    # the graph runs use the shipped default: learned BVs (one batched policy pass in the BV node)
    summary = run_inprocess(scenario_config(model, GRAPH_STEPS, "learned"), bag_dir=tmp_path / "bag")
    assert summary.steps == GRAPH_STEPS
    graph_bag = (out / "bag" / "bag_0.mcap").read_bytes()
    inprocess_bag = (tmp_path / "bag" / "bag_0.mcap").read_bytes()
    assert graph_bag == inprocess_bag, f"{model}: graph and in-process bags differ"


def test_sut_node_unknown_model_lists_the_choices(tmp_path: Path) -> None:
    from evoscen_bringup.graph_runner import GraphOptions, node_environment, write_parameter_files
    from evoscen_sim.model_registry import model_names

    params = write_parameter_files(scenario_config("mobil", 10), tmp_path, tmp_path / "bag", GraphOptions())
    res = subprocess.run([sys.executable, "-m", "evoscen_sut.sut_node", "--ros-args", "--params-file",
                          str(params["evoscen_sut"]), "-p", "model:=no_such_model"],
                         env=node_environment(0, "LOCALHOST"), capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 2, (res.returncode, res.stderr)
    assert "Traceback" not in res.stderr, res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert "model" in lines[0] and "no_such_model" in lines[0], lines[0]
    choices = model_names("sut")
    assert set(MODELS) <= set(choices)
    assert ", ".join(choices) in lines[0], lines[0]
