"""SUT mutants (docs/mutants.md) in both runners: a stateful mutant in the node graph (its SUT node
builds the mutant through the registry and decides from the world table on the wire) records
the same bag, byte for byte, as the in-process run of the same scenario."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
STEPS = 300

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]


@pytest.mark.parametrize("name", ["stale", "ignores_new_follower"])
def test_graph_bag_of_a_mutant_equals_inprocess_bag(name: str, tmp_path: Path) -> None:
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_sim.config.scenario_config import dump_config, load_scenario_config
    from evoscen_sut.mutants import mutant_overrides

    path = tmp_path / "mutant.yaml"
    dump_config(load_scenario_config(None, {"steps": STEPS, "seed": 0, **mutant_overrides("mobil", name)}), path)
    out = tmp_path / "graph"
    res = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "graph", "--config", str(path),
                          "--out", str(out), "--quiet", "--no-plots"],
                         cwd=REPO, capture_output=True, text=True, timeout=240, check=False)
    assert res.returncode == 0, f"{res.stdout}\n{res.stderr}"
    assert f"steps: {STEPS} " in res.stdout and "evoscen_sut=0" in res.stdout, res.stdout
    cfg = load_scenario_config(path)
    assert cfg.sut.model == "mutant" and cfg.models["mutant"].operator == name
    summary = run_inprocess(cfg, bag_dir=tmp_path / "bag")
    assert summary.steps == STEPS
    assert (out / "bag" / "bag_0.mcap").read_bytes() == (tmp_path / "bag" / "bag_0.mcap").read_bytes()
