"""BV nodes (``bvs.nodes``; docs/architecture.md §5, "BV nodes"): the partition rule, its one-line
errors, and a run that does not depend on it.

* ``by_policy`` (default): one node per driver type present, in the mix's order; ``single``; N by id;
* an entering vehicle keeps its slot (id and policy code), so the rule holds for the whole run;
* the in-process runner drives and records the partition: world, events, SUT commands and the
  report are the same bytes for ``single``, ``by_policy``, ``4`` and ``25`` (five empty nodes), and
  the BV commands of the nodes, put together by id, are those of ``single``;
* a BV node started under a name the scenario has no BV node of exits 2 with one line naming them.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _cfg(**bvs):
    from evoscen_sim.config.scenario_config import config_from_dict

    return config_from_dict({"steps": 300, "seed": 3, "bvs": bvs})


@pytest.mark.parametrize("value, expected", [
    (0, "expected by_policy, single or a number of nodes in [1, 32]"),
    (33, "expected by_policy, single or a number of nodes in [1, 32]"),
    ("by_polcy", "expected by_policy, single or a number of nodes in [1, 32]; did you mean 'by_policy'?"),
    (True, "expected by_policy, single or a number of nodes in [1, 32]"),
    (2.5, "expected by_policy, single or a number of nodes in [1, 32]"),
])
def test_bad_bv_nodes_is_one_line(value, expected):
    from evoscen_sim.config.scenario_config import config_from_dict
    from evoscen_sim.errors import InputError

    with pytest.raises(InputError) as exc:
        config_from_dict({"bvs": {"nodes": value}})
    text = str(exc.value)
    assert "\n" not in text and "key 'bvs.nodes'" in text and expected in text, text


def test_bad_bv_nodes_on_the_command_line_is_one_line():
    res = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--bv-nodes", "zero",
                          "--steps", "5", "--no-record"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        "error: command line: key 'bvs.nodes' = 'zero': expected by_policy, single or a number of nodes in [1, 32] "
        f"(overriding {REPO}/ros2_ws/src/evoscen_sim/config/default_scenario.yaml)"], res.stderr


def test_partition_rule():
    from evoscen_sim.nodes.bv_nodes import bv_nodes
    from evoscen_sim.scenario_builders import build_world

    # by_policy: 20 BVs at 4:3:3 are 8 competitive, 6 mutual, 6 cooperative (mix_counts), one node each,
    # in the mix's order; each node's rows are exactly the BVs of its policy in the world
    cfg = _cfg()
    nodes = bv_nodes(cfg)
    assert [n.name for n in nodes] == ["evoscen_bv_competitive", "evoscen_bv_mutual", "evoscen_bv_cooperative"]
    assert [n.topic for n in nodes] == ["/evoscen/commands/bv_competitive", "/evoscen/commands/bv_mutual",
                                        "/evoscen/commands/bv_cooperative"]
    assert [n.rows.size for n in nodes] == [8, 6, 6]
    world = build_world(cfg)
    for node, code in zip(nodes, (2, 1, 3)):  # POLICY_CODES: mutual 1, competitive 2, cooperative 3
        assert set(world.policy[node.rows].tolist()) == {code}
    assert sorted(np.concatenate([n.rows for n in nodes]).tolist()) == list(range(1, 21))
    # a policy with no share has no node
    assert [n.name for n in bv_nodes(_cfg(mix={"competitive": 1, "mutual": 0, "cooperative": 1}))] == [
        "evoscen_bv_competitive", "evoscen_bv_cooperative"]
    # a rule-based driver: one node named after it
    assert [(n.name, n.rows.size) for n in bv_nodes(_cfg(driver="level0"))] == [("evoscen_bv_level0", 20)]
    # single: the one node of old, its topic unchanged
    [single] = bv_nodes(_cfg(nodes="single"))
    assert (single.name, single.topic, single.rows.tolist()) == ("evoscen_bv", "/evoscen/commands/bv",
                                                                 list(range(1, 21)))
    # N: runs of consecutive ids, as even as can be (np.array_split: 20 in 4 = 5 each; 20 in 7 = 3 × 6 + 2)
    assert [n.rows.tolist() for n in bv_nodes(_cfg(nodes=4))] == [[1, 2, 3, 4, 5], [6, 7, 8, 9, 10],
                                                                  [11, 12, 13, 14, 15], [16, 17, 18, 19, 20]]
    assert [n.rows.size for n in bv_nodes(_cfg(nodes=7))] == [3, 3, 3, 3, 3, 3, 2]
    assert [n.name for n in bv_nodes(_cfg(nodes=3))] == ["evoscen_bv_0", "evoscen_bv_1", "evoscen_bv_2"]
    # more nodes than BVs: the last ones host nobody
    many = bv_nodes(_cfg(nodes=25))
    assert [n.rows.size for n in many] == [1] * 20 + [0] * 5
    # no BVs: no BV node, whatever the mode
    from evoscen_sim.config.scenario_config import config_from_dict

    for mode in ("by_policy", "single", 3):
        assert bv_nodes(config_from_dict({"bvs": {"count": 0, "nodes": mode}, "spawn": {"ramp_vehicles": 0}})) == ()


def test_entries_keep_their_node():
    """An entry at a window edge reuses its slot: the policy column of every vehicle is the same at
    every step of a run with entries (so the id -> node rule holds for the whole run)."""
    from evoscen_bringup.inprocess import run_inprocess

    summary = run_inprocess(_cfg(), bag_dir=None, evaluate=True, keep_run=True)
    assert summary.reentries > 0, "no entry in 300 steps: pick another seed"
    policy = summary.run.columns["policy"]
    assert (policy == policy[0]).all()


@pytest.fixture(scope="module")
def partitioned_bags(tmp_path_factory):
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_record.bag_reader import open_bag_reader

    root = tmp_path_factory.mktemp("partitions")
    out = {}
    for mode in ("single", "by_policy", 4, 25):
        bag_dir = root / str(mode) / "bag"
        summary = run_inprocess(_cfg(nodes=mode), bag_dir=bag_dir, evaluate=True, bag_writer="inline")
        topics: dict[str, list] = {}
        for topic, _type, t_ns, data in open_bag_reader(bag_dir):
            topics.setdefault(topic, []).append((t_ns, data))
        out[mode] = (topics, summary.report)
    return out


@pytest.mark.parametrize("mode", ["by_policy", 4, 25])
def test_world_events_and_report_do_not_depend_on_the_partition(partitioned_bags, mode):
    single, report = partitioned_bags["single"]
    other, other_report = partitioned_bags[mode]
    shared = ("/clock", "/evoscen/world", "/evoscen/events", "/evoscen/sut/odom", "/evoscen/commands/sut",
              "/evoscen/roster", "/evoscen/markers", "/evoscen/map_markers")
    for topic in shared:
        assert other[topic] == single[topic], topic
    assert other_report == report
    # the BV commands: one topic per node, one message per step each (an empty table from a node
    # without BVs), which together are the single node's commands, row for row by id
    from evoscen_contract.cdr import decode_table

    bv_topics = [t for t in other if t.startswith("/evoscen/commands/bv_")]
    assert len(bv_topics) == {"by_policy": 3, 4: 4, 25: 25}[mode]
    steps = len(single["/evoscen/commands/bv"])
    assert steps == 300
    for k in (0, 1, 150, 299):
        t_ns, data = single["/evoscen/commands/bv"][k]
        whole = decode_table(data).data
        parts = []
        for topic in bv_topics:
            assert len(other[topic]) == steps, topic
            t, d = other[topic][k]
            assert t == t_ns
            parts.append(decode_table(d).data)
        joined = np.concatenate(parts)
        joined = joined[np.argsort(joined[:, 0])]
        assert joined.tobytes() == whole.tobytes(), f"step {k}"


def test_bv_node_with_a_name_outside_the_partition_is_one_line(tmp_path):
    from evoscen_bringup.graph_runner import GraphOptions, write_parameter_files
    from evoscen_sim.config.scenario_config import load_scenario_config

    files = write_parameter_files(load_scenario_config(None, {"steps": 20}), tmp_path, tmp_path / "bag",
                                  GraphOptions())
    path = files["evoscen_bv_mutual"]
    text = path.read_text().replace("evoscen_bv_mutual:", "evoscen_bv_nosuch:", 1)
    bad = tmp_path / "nosuch.yaml"
    bad.write_text(text)
    res = subprocess.run([sys.executable, "-m", "evoscen_bv.bv_node", "--ros-args", "--params-file", str(bad),
                          "-r", "__node:=evoscen_bv_nosuch"], cwd=REPO, capture_output=True, text=True, timeout=120)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, res.stderr
    assert lines == ["error: BV node 'evoscen_bv_nosuch' is not one of this scenario's BV nodes (bvs.nodes = "
                     "by_policy): evoscen_bv_competitive, evoscen_bv_mutual, evoscen_bv_cooperative"], lines


@pytest.mark.e2e
def test_bv_node_started_by_hand_joins_the_run(tmp_path):
    """``--wait-for evoscen_bv_mutual``: the launcher starts every node but that BV node, which is
    started by hand from the parameter file the launcher wrote (the commands of docs/architecture.md
    §5, "BV nodes"); the simulation waits for it, and the bag is the in-process run's, byte for byte."""
    import os
    import time

    from evoscen_bringup.domains import reserve_domain, reserved_by_caller_env
    from evoscen_bringup.graph_runner import node_environment

    out, inproc = tmp_path / "graph", tmp_path / "inproc"
    with reserve_domain(None) as domain:
        launcher = subprocess.Popen(
            [sys.executable, "scripts/run_scenario.py", "--mode", "graph", "--steps", "150", "--seed", "5",
             "--out", str(out), "--no-plots", "--domain-id", str(domain), "--wait-for", "evoscen_bv_mutual"],
            cwd=REPO, env=dict(os.environ, **reserved_by_caller_env(domain)), text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        params = out / "params" / "evoscen_bv_mutual.yaml"
        end = time.monotonic() + 60
        while not params.exists() and time.monotonic() < end:
            time.sleep(0.05)
        assert params.exists(), "the launcher wrote no parameter file for the BV node to start by hand"
        by_hand = subprocess.Popen(
            [sys.executable, "-m", "evoscen_bv.bv_node", "--ros-args", "--params-file", str(params),
             "-r", "__node:=evoscen_bv_mutual"],
            cwd=REPO, env=node_environment(domain, "LOCALHOST"), text=True,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        try:
            stdout, stderr = launcher.communicate(timeout=180)
            hand_out, _ = by_hand.communicate(timeout=60)
        finally:
            for p in (launcher, by_hand):
                if p.poll() is None:
                    p.kill()
                    p.communicate()
    assert launcher.returncode == 0, f"{stdout}\n{stderr}"
    assert by_hand.returncode == 0, hand_out
    # the launcher started and supervised the other nodes only
    assert ("nodes: evoscen_eval=0, evoscen_bv_competitive=0, evoscen_bv_cooperative=0, evoscen_sut=0, "
            "evoscen_sim=0") in stdout, stdout
    res = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", "--steps", "150",
                          "--seed", "5", "--out", str(inproc), "--no-plots", "--quiet"],
                         cwd=REPO, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    assert (out / "bag" / "bag_0.mcap").read_bytes() == (inproc / "bag" / "bag_0.mcap").read_bytes()
    assert (out / "bag" / "metadata.yaml").read_bytes() == (inproc / "bag" / "metadata.yaml").read_bytes()


@pytest.mark.e2e
def test_graph_with_an_empty_bv_node_equals_inprocess(tmp_path):
    """3 BVs over 4 BV nodes (``--bv-nodes 4``): evoscen_bv_3 hosts nobody and still answers every
    step with an empty table; the graph's bag is the in-process run's, byte for byte."""
    from evoscen_record.bag_reader import open_bag_reader

    common = ["--steps", "120", "--seed", "2", "--bvs", "3", "--bv-nodes", "4", "--no-plots"]
    graph = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "graph", *common,
                            "--out", str(tmp_path / "graph")], cwd=REPO, capture_output=True, text=True, timeout=240)
    assert graph.returncode == 0, graph.stdout + graph.stderr
    assert ("nodes: evoscen_eval=0, evoscen_bv_0=0, evoscen_bv_1=0, evoscen_bv_2=0, evoscen_bv_3=0, evoscen_sut=0, "
            "evoscen_sim=0") in graph.stdout, graph.stdout
    inproc = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "inprocess", *common, "--quiet",
                             "--out", str(tmp_path / "inproc")], cwd=REPO, capture_output=True, text=True, timeout=240)
    assert inproc.returncode == 0, inproc.stderr
    g, i = tmp_path / "graph" / "bag", tmp_path / "inproc" / "bag"
    assert (g / "bag_0.mcap").read_bytes() == (i / "bag_0.mcap").read_bytes()
    from evoscen_contract.cdr import decode_table

    empty = [decode_table(d).data.shape[0] for t, _ty, _ns, d in open_bag_reader(g) if t == "/evoscen/commands/bv_3"]
    assert empty == [0] * 120
