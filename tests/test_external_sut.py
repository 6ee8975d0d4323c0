"""The external-SUT example (examples/external_sut_node.py) joins a node-graph run in place of
evoscen's SUT node and drives the SUT in lockstep.

The graph's nodes are started here, as the launcher does (its parameter files, its node
environment) but without ``evoscen_sut``, on a ROS_DOMAIN_ID reserved on the host as the
launcher reserves its own (``evoscen_bringup.domains``) with localhost discovery; the example
node is started next to them on the same domain. The bag must then hold
one SUT command per step, stamped like the world message it answers, whose values are what
the example's policy computes from that recorded world table (recomputed here).
"""

from __future__ import annotations

import contextlib
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "external_sut_node.py"
STEPS = 100
FINAL_STEPS = 20
SEED = 11

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]


def load_example():
    """The example as a module (its policy and table decoding are pure functions)."""
    spec = importlib.util.spec_from_file_location("external_sut_node", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(spec.name, module)  # dataclasses look their module up while it runs
    spec.loader.exec_module(sys.modules[spec.name])
    return sys.modules[spec.name]


def start_graph_with_external_sut(out: Path, domain_id: int, *, steps: int, example_args: list[str]) -> dict:
    """Start evaluator, BV and simulation nodes plus the example (not waiting for them)."""
    from evoscen_bringup.graph_runner import GraphOptions, node_environment, write_parameter_files
    from evoscen_sim.config.scenario_config import load_scenario_config

    out.mkdir(parents=True, exist_ok=True)
    cfg = load_scenario_config(None, {"steps": steps, "seed": SEED, "bvs.nodes": "single"})  # one BV node, started here
    params = write_parameter_files(cfg, out, out / "bag", GraphOptions(startup_timeout_s=60.0, external_sut=True))
    env = node_environment(domain_id, "LOCALHOST")
    commands = {
        "evoscen_eval": ["-m", "evoscen_eval.eval_node", "--ros-args", "--params-file", str(params["evoscen_eval"])],
        "evoscen_bv": ["-m", "evoscen_bv.bv_node", "--ros-args", "--params-file", str(params["evoscen_bv"])],
        "external_sut": [str(EXAMPLE), "--ros-args", *example_args],
        "evoscen_sim": ["-m", "evoscen_sim.nodes.sim_node", "--ros-args", "--params-file", str(params["evoscen_sim"])],
    }
    return {name: subprocess.Popen([sys.executable, *argv], env=env, cwd=out, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, text=True)
            for name, argv in commands.items()}


def wait_for(procs: dict, out: Path) -> dict:
    """Exit status and output of every node once the run is over; ``bag_dir``."""
    result = {}
    try:
        for name in ("evoscen_sim", "evoscen_eval", "external_sut", "evoscen_bv"):
            output, _ = procs[name].communicate(timeout=120)
            result[name] = (procs[name].returncode, output)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
    result["bag_dir"] = out / "bag"
    return result


def read_bag(bag_dir: Path) -> dict[str, list[tuple[int, bytes]]]:
    from evoscen_record.bag_reader import open_bag_reader

    topics: dict[str, list[tuple[int, bytes]]] = {}
    for topic, _type, t_ns, data in open_bag_reader(bag_dir):
        topics.setdefault(topic, []).append((t_ns, data))
    return topics


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Two runs at once: the example told the number of steps (STEPS), and the example not
    told it (FINAL_STEPS: it then answers the final state too)."""
    from evoscen_bringup.domains import reserve_domain

    root = tmp_path_factory.mktemp("external_sut")
    with contextlib.ExitStack() as held:  # each graph's domain reserved until its nodes have ended
        told, untold = (held.enter_context(reserve_domain(None)) for _ in range(2))
        started = {"told": (start_graph_with_external_sut(root / "told", told, steps=STEPS,
                                                          example_args=["-p", f"steps:={STEPS}"]), root / "told"),
                   "untold": (start_graph_with_external_sut(root / "untold", untold, steps=FINAL_STEPS,
                                                            example_args=[]), root / "untold")}
        return {key: wait_for(procs, out) for key, (procs, out) in started.items()}


@pytest.fixture(scope="module")
def external_run(runs: dict) -> dict:
    return runs["told"]


def test_external_sut_runs_to_completion(external_run: dict) -> None:
    for name in ("evoscen_sim", "evoscen_eval", "external_sut", "evoscen_bv"):
        status, output = external_run[name]
        assert status == 0, f"{name} exited with {status}:\n{output}"
    assert f"answered {STEPS} world messages" in external_run["external_sut"][1]


def test_bag_holds_the_policy_of_every_step(external_run: dict) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_contract.tables import ns_from_stamp, table_columns
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2

    example = load_example()
    topics = read_bag(external_run["bag_dir"])
    worlds = topics["/evoscen/world"]
    commands = topics["/evoscen/commands/sut"]
    assert len(worlds) == STEPS + 1  # the final state too
    assert len(commands) == STEPS
    for (t_world, world_data), (t_cmd, cmd_data) in zip(worlds, commands):
        world = deserialize_message(world_data, PointCloud2)
        cmd = deserialize_message(cmd_data, PointCloud2)
        assert t_cmd == t_world == ns_from_stamp(cmd.header.stamp)
        assert cmd.header.frame_id == "map"
        got = table_columns(cmd)
        assert tuple(got) == example.COMMAND_FIELDS and len(got["id"]) == 1
        # the example decodes by field name what evoscen's own decoder reads
        mine = example.table_columns(world)
        ours = table_columns(world)
        assert all(np.array_equal(mine[k], ours[k]) for k in ours)
        vehicle_id, throttle, lane_change = example.policy(mine)
        assert (got["id"][0], got["throttle"][0], got["lane_change"][0]) == (vehicle_id, throttle, lane_change)
        assert vehicle_id == ours["id"][ours["role"] == 1][0]
    # lockstep: no controller ever missed a deadline, and the SUT was driven, not held
    events = [deserialize_message(d, DiagnosticArray) for _, d in topics["/evoscen/events"]]
    names = [s.name for e in events for s in e.status]
    assert "evoscen/fault" not in names
    assert names[-1] == "evoscen/run_end"
    throttles = [table_columns(deserialize_message(d, PointCloud2))["throttle"][0] for _, d in commands]
    assert len(set(throttles)) > 10


def test_answering_the_final_state_too_leaves_one_command_per_step(runs: dict) -> None:
    res = runs["untold"]
    for name in ("evoscen_sim", "evoscen_eval", "external_sut", "evoscen_bv"):
        assert res[name][0] == 0, f"{name}: {res[name][1]}"
    assert f"answered {FINAL_STEPS + 1} world messages" in res["external_sut"][1]
    assert len(read_bag(res["bag_dir"])["/evoscen/commands/sut"]) == FINAL_STEPS


def test_bag_and_report_name_the_sut_external(external_run: dict) -> None:
    """The configuration's sut.model drove nothing in this run: the bag's metadata says the SUT was
    external, and a report made from the bag names it so rather than the configured model."""
    from evoscen_eval.scoring.metrics import run_info
    from evoscen_eval.scoring.rundata import read_run

    run = read_run(external_run["bag_dir"])
    assert run.external_sut is True
    assert run.scenario["sut"]["model"] != "external"  # the configuration itself is recorded unchanged
    assert run_info(run)["sut_model"] == "external"
