"""Acceptance tests of the ROS 2 node graph (``run_scenario.py --mode graph``): real processes,
real rclpy + Fast DDS, no mocks.

* a 200-step run completes and its bag holds every step;
* the graph's bag is byte-identical to the in-process bag of the same config and seed;
* a controller killed mid-run is a clean abort at the step it owes (status 4, one error line naming it, a finished bag
  holding every step up to the fault);
* the terminal holds the launcher's lines only: each node's output (rclpy's log lines too) is in ``OUT/logs/<node>.log``,
  and the one error line of a failed run names that folder;
* Ctrl-C (SIGINT to the launcher) leaves a finished bag (status 130, run_end ``interrupted``);
* the recorder killed mid-run is reported as one line, not a traceback;
* a node started with a bad parameter exits 2 with one line naming the parameter;
* the launcher's parameter files (``OUT/params/<node>.yaml``) load back with the scenario values.

Every graph runs on its own ROS_DOMAIN_ID (the launcher reserves one on the host; nodes a test
starts itself run on a domain the test has reserved the same way) with localhost-only discovery. Only processes started by a test are signalled:
node processes are found as children of the test's own launcher (``pgrep -P <launcher pid>``),
never by name alone (other graphs may run on the same machine).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter, defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]

REPO = Path(__file__).resolve().parents[1]
SCRIPT = "scripts/run_scenario.py"
DT_NS = 100_000_000  # dt_s of the shipped config
N_VEHICLES = 21  # 1 SUT + 20 BVs (shipped config)
BV_NODES = ("evoscen_bv_competitive", "evoscen_bv_mutual", "evoscen_bv_cooperative")
"""The BV nodes of the default scenario (bvs.nodes: by_policy, mix 4:3:3; docs/architecture.md §5, "BV nodes")."""
BV_TOPICS = tuple("/evoscen/commands/" + n.removeprefix("evoscen_") for n in BV_NODES)
NODES = ("evoscen_eval", *BV_NODES, "evoscen_sut", "evoscen_sim")
NODES_LINE = "nodes: evoscen_eval=0, " + ", ".join(f"{n}=0" for n in BV_NODES) + ", evoscen_sut=0, evoscen_sim="
PER_STEP_STATE = ("/clock", "/evoscen/world", "/evoscen/sut/odom")  # published at t_0 .. t_N


# --------------------------------------------------------------------------- helpers


@pytest.fixture(scope="module")
def own_domain():
    """A ROS_DOMAIN_ID reserved on the host (as the launcher reserves its own) for the lone
    nodes this module starts itself, so that they never join another graph's domain."""
    from evoscen_bringup.domains import reserve_domain

    with reserve_domain(None) as domain:
        yield domain


def _node_env(domain_id: int) -> dict[str, str]:
    """Environment for a process of the test itself that joins a graph's domain (localhost only)."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


def _run_cli(*args: object, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, SCRIPT, *map(str, args)], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout, check=False)


def _launch(*args: object) -> subprocess.Popen:
    """Start the launcher (``--mode graph``) in the background."""
    return subprocess.Popen([sys.executable, SCRIPT, "--mode", "graph", *map(str, args)], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _children(launcher: subprocess.Popen, module: str = "") -> list[int]:
    """Pids of the launcher's own node processes (optionally only the one running ``module``)."""
    cmd = ["pgrep", "-P", str(launcher.pid)] + (["-f", rf"\s-m {re.escape(module)}(\s|$)"] if module else [])
    out = subprocess.run(cmd, capture_output=True, text=True, check=False).stdout
    return [int(pid) for pid in out.split()]


def _wait_running(launcher: subprocess.Popen, bag_dir: Path, timeout: float = 90.0) -> None:
    """Until the run is in progress: the recorder has written steps (the bag file grows)."""
    mcap = bag_dir / "bag_0.mcap"
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if launcher.poll() is not None:
            out, err = launcher.communicate()
            pytest.fail(f"the launcher ended ({launcher.returncode}) before the run got going:\n{out}\n{err}")
        if mcap.exists() and mcap.stat().st_size > 0:
            return
        time.sleep(0.1)
    pytest.fail(f"the run did not start within {timeout:g} s (no data in {mcap})")


def _terminate(launcher: subprocess.Popen) -> None:
    """Clean-up after a failed test: end the launcher and its node processes (ours only)."""
    if launcher.poll() is not None:
        return
    pids = _children(launcher)
    launcher.kill()
    launcher.communicate()
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@contextmanager
def _running(bag_dir: Path, *args: object, settle_s: float = 0.0) -> Iterator[subprocess.Popen]:
    """The launcher of ``_launch(*args)``, once its run is in progress (``_wait_running`` on
    ``bag_dir``) and ``settle_s`` seconds more; ended with ``_terminate`` on the way out."""
    launcher = _launch(*args)
    try:
        _wait_running(launcher, bag_dir)
        if settle_s:
            time.sleep(settle_s)
        yield launcher
    finally:
        _terminate(launcher)


def _read_bag(bag_dir: Path) -> dict[str, list[tuple[int, bytes]]]:
    """``{topic: [(log_time_ns, cdr bytes), ...]}`` in file order (evoscen's reader)."""
    from evoscen_record.bag_reader import open_bag_reader

    out: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    for topic, _type, t_ns, data in open_bag_reader(bag_dir):
        out[topic].append((t_ns, data))
    return out


def _events(bag: dict[str, list[tuple[int, bytes]]]) -> list[tuple[int, dict]]:
    """Every event of the bag with the stamp of its message, in order."""
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_contract.topics import parse_events
    from rclpy.serialization import deserialize_message

    return [(t, ev) for t, data in bag.get("/evoscen/events", [])
            for ev in parse_events(deserialize_message(data, DiagnosticArray))]


def _mcap_summary_count(bag_dir: Path) -> int:
    """The message count of the MCAP summary section (present only in a finished file)."""
    from mcap.reader import make_reader

    with open(bag_dir / "bag_0.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None, f"{bag_dir}: no MCAP summary (bag not finished)"
    return summary.statistics.message_count


def _stamps(bag: dict, topic: str) -> list[int]:
    return [t for t, _ in bag.get(topic, [])]


def _steps(stamps: list[int]) -> list[int]:
    assert all(t % DT_NS == 0 for t in stamps), f"stamps not on the step grid: {stamps[:5]}"
    return [t // DT_NS for t in stamps]


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error:")]


RAW_LOG_LINE = re.compile(r"^\[(WARN|ERROR|INFO|DEBUG|FATAL)\] \[\d+\.\d+\]", re.M)
"""A line of rclpy's console logger: it belongs in a node's log file, not on the launcher's terminal."""


def _node_logs(out: Path) -> dict[str, str]:
    """The log files of a graph run (``OUT/logs/<name>.log``: each node's output, the launcher's events), by name."""
    return {p.stem: p.read_text(encoding="utf-8", errors="replace") for p in sorted((out / "logs").glob("*.log"))}


def _assert_clean_terminal(stdout: str, stderr: str, out: Path) -> dict[str, str]:
    """No node's line on the terminal (no rclpy log line, no line a node prints with its name) and no traceback
    anywhere, the node logs included; returns the logs."""
    logs = _node_logs(out)
    assert set(NODES) <= set(logs) and "launcher" in logs, sorted(logs)
    terminal = stdout + stderr
    assert not RAW_LOG_LINE.search(terminal), terminal
    assert not re.search(r"^evoscen_\w+: ", terminal, re.M), terminal
    assert "Traceback" not in terminal and not any("Traceback" in text for text in logs.values()), logs
    return logs


# --------------------------------------------------------------------------- 200-step run


@pytest.fixture(scope="module")
def graph_200(tmp_path_factory):
    """``--mode graph --steps 200 --seed 5`` and ``--mode inprocess`` of the same scenario."""
    root = tmp_path_factory.mktemp("graph200")
    t0 = time.monotonic()
    graph = _run_cli("--mode", "graph", "--steps", 200, "--seed", 5, "--out", root / "graph")
    wall = time.monotonic() - t0
    inproc = _run_cli("--mode", "inprocess", "--steps", 200, "--seed", 5, "--out", root / "inproc", "--quiet")
    assert inproc.returncode == 0, inproc.stderr
    return {"out": root / "graph", "res": graph, "wall": wall, "inproc_out": root / "inproc"}


def test_graph_run_completes(graph_200):
    res, bag_dir = graph_200["res"], graph_200["out"] / "bag"
    assert res.returncode == 0, f"graph run failed ({res.returncode}):\n{res.stdout}\n{res.stderr}"
    assert not _error_lines(res.stderr) and "Traceback" not in res.stderr, res.stderr
    logs = _assert_clean_terminal(res.stdout, res.stderr, graph_200["out"])
    assert res.stderr.splitlines() == [line for line in res.stderr.splitlines() if line.startswith("graph: ")], res.stderr
    assert re.search(r"^evoscen_sim: lockstep: 200 steps in ", logs["evoscen_sim"], re.M), logs["evoscen_sim"]
    assert re.search(r"^steps: 200\b", res.stdout, re.MULTILINE), res.stdout
    assert NODES_LINE + "0" in res.stdout, res.stdout
    bag = _read_bag(bag_dir)
    for topic in PER_STEP_STATE:
        assert _steps(_stamps(bag, topic)) == list(range(201)), topic
    for topic in (*BV_TOPICS, "/evoscen/commands/sut"):
        assert _steps(_stamps(bag, topic)) == list(range(200)), topic
    assert len(bag["/evoscen/roster"]) == 1
    # events after every step (stamped t_1 .. t_200, empty when nothing happened), then run_end
    assert _steps(_stamps(bag, "/evoscen/events")) == [*range(1, 201), 200]
    ends = [(t, ev) for t, ev in _events(bag) if ev["name"] == "evoscen/run_end"]
    assert len(ends) == 1 and ends[0][1]["kind"] == "completed" and ends[0][0] == 200 * DT_NS, ends
    assert not [ev for _, ev in _events(bag) if ev["name"] == "evoscen/fault"]
    assert _mcap_summary_count(bag_dir) == sum(len(v) for v in bag.values())
    print(f"\ngraph 200 steps: {graph_200['wall']:.1f} s wall (launcher)")


def test_graph_bag_equals_inprocess_bag(graph_200):
    assert graph_200["res"].returncode == 0, graph_200["res"].stderr
    g_dir, i_dir = graph_200["out"] / "bag", graph_200["inproc_out"] / "bag"
    g, i = _read_bag(g_dir), _read_bag(i_dir)
    assert sorted(g) == sorted(i), "different topics"
    # message by message first, for a failure that says where
    for topic in ("/evoscen/world", *BV_TOPICS, "/evoscen/commands/sut", *sorted(i)):
        assert _stamps(g, topic) == _stamps(i, topic), f"{topic}: different stamps"
        for (t, a), (_, b) in zip(g[topic], i[topic]):
            assert a == b, f"{topic} at t = {t / 1e9:g} s: graph and in-process messages differ"
    assert (g_dir / "metadata.yaml").read_bytes() == (i_dir / "metadata.yaml").read_bytes(), "metadata.yaml differs"
    assert (g_dir / "bag_0.mcap").read_bytes() == (i_dir / "bag_0.mcap").read_bytes(), "bag_0.mcap differs"


def test_live_report_equals_offline_and_inprocess(graph_200, tmp_path):
    """The evaluator node's report.json (live) = evaluate.py on the bag (offline) = the in-process runner's."""
    assert graph_200["res"].returncode == 0, graph_200["res"].stderr
    live = json.loads((graph_200["out"] / "report" / "report.json").read_text())
    inproc = json.loads((graph_200["inproc_out"] / "report" / "report.json").read_text())
    res = subprocess.run([sys.executable, "scripts/evaluate.py", str(graph_200["out"] / "bag"), "--out",
                          str(tmp_path / "offline"), "--no-plots"], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    offline = json.loads((tmp_path / "offline" / "report.json").read_text())
    offline["run"].pop("source")
    assert live == offline == inproc
    assert live["run"]["steps"] == 200 and live["run"]["complete"] is True and live["complexity"]["windows"] == 2
    # C and E enter I_s scaled to 3,000 steps (evaluation.count_normalisation: method_length), live as offline
    s = live["safety"]
    assert (s["count_normalisation"], s["steps"], s["count_factor"]) == ("method_length", 200, 15.0)
    assert (s["collisions_used"], s["exposures_used"]) == (15 * s["collisions"], 15 * s["exposures"])
    for name in ("report.md", "ttc.png", "speed.png", "timeline.png", "traffic.png"):
        assert (graph_200["out"] / "report" / name).stat().st_size > 0, name
    out = graph_200["res"].stdout
    assert out.index("D, the comparative score: ") < out.index("the method's intelligence I (for reproducing the paper): ")


def test_parameter_files_written_and_load_back(graph_200):
    from evoscen_sim.config.scenario_config import config_from_dict, load_scenario_config
    from evoscen_sim.nodes.node_params import scenario_parameters

    out = graph_200["out"]
    cfg = load_scenario_config(out / "scenario.yaml")
    assert (cfg.steps, cfg.seed, cfg.bvs.count) == (200, 5, 20)
    for node in NODES:
        path = out / "params" / f"{node}.yaml"
        assert path.is_file(), path
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        assert list(doc) == [node] and list(doc[node]) == ["ros__parameters"], f"{path}: not 'node: ros__parameters:'"
        params = doc[node]["ros__parameters"]
        assert params["scenario"] == scenario_parameters(cfg), f"{path}: scenario parameters differ"
        assert config_from_dict(params["scenario"], source=str(path)) == cfg, f"{path}: does not load back"
        assert params["scenario"]["steps"] == 200 and params["scenario"]["seed"] == 5
        assert params["scenario"]["bvs"]["count"] == 20
    sim = yaml.safe_load((out / "params" / "evoscen_sim.yaml").read_text())["evoscen_sim"]["ros__parameters"]
    assert (sim["deadline_s"], sim["max_misses"]) == (2.0, 5)
    assert sim["controllers"] == [*BV_NODES, "evoscen_sut"]
    ev = yaml.safe_load((out / "params" / "evoscen_eval.yaml").read_text())["evoscen_eval"]["ros__parameters"]
    assert Path(ev["bag_dir"]) == out / "bag"


# --------------------------------------------------------------------------- a controller dies


@pytest.fixture(scope="module", params=BV_NODES)
def killed_bv(request, tmp_path_factory):
    """A long run one of whose BV nodes (each in turn) is SIGKILLed mid-run (deadline 0.5 s, 3 misses abort)."""
    name = request.param
    out = tmp_path_factory.mktemp("killbv") / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--deadline", 0.5, "--max-misses", 3, "--out", out,
                  settle_s=0.3) as launcher:
        assert len(_children(launcher, "evoscen_bv.bv_node")) == len(BV_NODES)
        cmd = ["pgrep", "-P", str(launcher.pid), "-f", rf"\s__node:={name}(\s|$)"]
        bv = [int(p) for p in subprocess.run(cmd, capture_output=True, text=True, check=False).stdout.split()]
        assert len(bv) == 1, f"expected one child of the launcher named {name}, found {bv}"
        os.kill(bv[0], signal.SIGKILL)
        t_kill = time.monotonic()
        stdout, stderr = launcher.communicate(timeout=120)
        after_kill = time.monotonic() - t_kill
    return {"name": name, "out": out, "rc": launcher.returncode, "stdout": stdout, "stderr": stderr,
            "after_kill": after_kill}


def test_killed_controller_aborts_cleanly(killed_bv):
    rc, stderr, bag_dir = killed_bv["rc"], killed_bv["stderr"], killed_bv["out"] / "bag"
    name = killed_bv["name"]
    print(f"\n{name} killed: launcher ended {killed_bv['after_kill']:.1f} s after the kill")
    # the launcher names the dead node to the simulation at once, which aborts at the step it waits
    # for (no deadline waits); then the nodes end: the controllers as soon as the simulation node has
    # withdrawn its publishers - not when its participant's lease runs out (20 s: was 22 s here)
    assert killed_bv["after_kill"] < 8.0, f"the graph took {killed_bv['after_kill']:.1f} s to end after the kill"
    # a death (4), not the simulation's controller fault (3) that follows it (docs/recording.md)
    assert rc == 4, f"exit status {rc}, expected 4 (a node died)\n{stderr}"
    logs = _assert_clean_terminal(killed_bv["stdout"], stderr, killed_bv["out"])
    errors = _error_lines(stderr)
    assert errors == [f"error: graph: node {name} ended early (killed by SIGKILL (signal 9)); the run ended early "
                      f"(exit status 4) (node logs: {killed_bv['out'] / 'logs'}/)"], \
        f"expected the launcher's one 'error:' line naming {name}\n{stderr}"
    # the simulation's abort, said as the consequence it is (no 'error:'), in its log; the launcher's log names the death
    assert re.search(rf"^evoscen_sim: controller '{name}' ended before answering step \d+; "
                     r"run aborted \(its process had ended: the launcher names it\)$", logs["evoscen_sim"], re.M), logs
    assert re.search(rf"^ +\d+\.\d s  {name} ended early \(killed by SIGKILL \(signal 9\)\)$", logs["launcher"], re.M), \
        logs["launcher"]
    assert f"{name}=-9" in killed_bv["stdout"], killed_bv["stdout"]  # the launcher reports the dead node
    assert "aborted: the run ended at step" in killed_bv["stdout"] and "comparative score" not in killed_bv["stdout"]

    bag = _read_bag(bag_dir)
    assert _mcap_summary_count(bag_dir) == sum(len(v) for v in bag.values())
    events = _events(bag)
    faults = [ev for _, ev in events if ev["name"] == "evoscen/fault"]
    # The run ends at the first step the dead controller did not answer. A live controller may miss a
    # deadline on a loaded machine too (seen on CI: the SUT node at K-2) - a 'deadline' fault that holds
    # its command, never an abort.
    assert faults and faults[-1]["kind"] == "abort", faults
    assert all(f["kind"] == "deadline" for f in faults[:-1]), faults
    # its misses: 1, the abort step, unless a deadline ran out before the launcher saw the death (loaded machine)
    missed = faults[-1]["misses"]
    assert faults[-1]["controller"] == name and missed >= 1, faults
    k = faults[-1]["step"]  # the step at which the run stopped (world t_K published, never integrated)
    ends = [(t, ev) for t, ev in events if ev["name"] == "evoscen/run_end"]
    assert len(ends) == 1 and ends[0][1]["kind"] == "aborted" and ends[0][0] == k * DT_NS, ends
    assert ends[0] == events[-1], "run_end is not the last event"
    assert 0 < k < 5000
    for topic in PER_STEP_STATE:  # every step up to the fault, none after it
        assert sorted(set(_steps(_stamps(bag, topic)))) == list(range(k + 1)), topic
        assert _stamps(bag, topic) == sorted(_stamps(bag, topic)), topic
    # The command tables in the bag are answers to the steps the run took, 0 .. K-1: an answer to K, whenever
    # it reached the recorder, is not recorded (docs/recording.md, "A controller that dies during a step")
    bv = _steps(_stamps(bag, BV_TOPICS[BV_NODES.index(name)]))
    for other in ["/evoscen/commands/sut", *(set(BV_TOPICS) - {BV_TOPICS[BV_NODES.index(name)]})]:
        got = _steps(_stamps(bag, other))  # the live controllers answered every step the run took
        assert got == list(range(k)), \
            f"{other}: expected steps 0 .. K-1 (K = {k}), got {len(got)} messages, the last {got[-5:]}; faults {faults}"
    # It died before its answer to K - missed + 1 reached the simulation node: the bag has its commands
    # 0 .. K - missed, or one fewer - the shared-memory transport hands a sample to each reader in turn, so
    # a process killed mid-publication can leave its last answer with the simulation node but not with the
    # recorder (seen in the container job) - but never an answer to a later step.
    assert bv in (list(range(k - missed)), list(range(k - missed + 1))), \
        f"BV commands: expected steps 0 .. K-{missed + 1} or K-{missed} (K = {k}), got {bv[-5:]}"
    assert len(bag["/evoscen/roster"]) == 1


def test_killed_controller_bag_has_one_message_per_step(killed_bv):
    bag = _read_bag(killed_bv["out"] / "bag")
    for topic in (*PER_STEP_STATE, "/evoscen/commands/sut"):
        dup = {t: n for t, n in Counter(_stamps(bag, topic)).items() if n > 1}
        assert not dup, f"{topic}: several messages with the same stamp {dup}"


def test_stalled_controller_is_a_controller_fault(tmp_path):
    """A BV node alive but stopped (SIGSTOP) misses its deadlines: the simulation's abort (3), its one
    'error:' line naming the node, the abort in the bag; not a death (4), which needs a process that ended."""
    name = BV_NODES[0]
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--deadline", 0.5, "--max-misses", 3, "--out", out,
                  "--no-plots", settle_s=0.3) as launcher:
        cmd = ["pgrep", "-P", str(launcher.pid), "-f", rf"\s__node:={name}(\s|$)"]
        bv = [int(p) for p in subprocess.run(cmd, capture_output=True, text=True, check=False).stdout.split()]
        assert len(bv) == 1, bv
        os.kill(bv[0], signal.SIGSTOP)
        end = time.monotonic() + 60
        while _children(launcher, "evoscen_sim.nodes.sim_node") and time.monotonic() < end:
            time.sleep(0.1)
        os.kill(bv[0], signal.SIGCONT)  # the run is over: it sees the world's publisher gone and ends
        stdout, stderr = launcher.communicate(timeout=90)
    assert launcher.returncode == 3, f"exit status {launcher.returncode}, expected 3\n{stdout}\n{stderr}"
    logs = _assert_clean_terminal(stdout, stderr, out)
    errors = _error_lines(stderr)
    assert len(errors) == 1 and re.fullmatch(
        rf"error: evoscen_sim: controller '{name}' missed 3 consecutive deadline\(s\) of 0.5 s at step \d+; "
        rf"run aborted \(node logs: {re.escape(str(out / 'logs'))}/\)", errors[0]), errors
    assert errors[0].removeprefix("error: ").split(" (node logs")[0] in logs["evoscen_sim"], logs["evoscen_sim"]
    assert "ended early" not in stderr, stderr
    faults = [ev for _, ev in _events(_read_bag(out / "bag")) if ev["name"] == "evoscen/fault"]
    assert faults[-1]["kind"] == "abort" and faults[-1]["controller"] == name, faults


def test_exit_status_precedence():
    """graph_status, the table's order (docs/recording.md): a death before the deadline abort it causes."""
    from evoscen_bringup.graph_runner import graph_status
    from evoscen_contract.contract import NODE_EVAL, NODE_SIM, NODE_SUT

    bv, killed = BV_NODES[1], "ended early (killed by SIGKILL (signal 9))"
    ok = {NODE_SIM: 0, NODE_EVAL: 0, **{n: 0 for n in BV_NODES}, NODE_SUT: 0}
    assert graph_status(ok, {}, False) == 0
    # a BV node killed in the lockstep, the simulation's abort (3) following: 4
    assert graph_status({**ok, NODE_SIM: 3, bv: -9}, {bv: killed}, False, [bv]) == 4
    # a controller that exits 1 on its own (a crash) during the run: 4 as well
    assert graph_status({**ok, NODE_SIM: 3, NODE_SUT: 1}, {NODE_SUT: "ended early (exit status 1)"}, False,
                        [NODE_SUT]) == 4
    # a live controller that missed its deadlines (stalled; stopped by the launcher after the run): 3
    assert graph_status({**ok, NODE_SIM: 3}, {}, False) == 3
    assert graph_status({**ok, NODE_SIM: 3, bv: -9}, {}, False, []) == 3
    # a controller that refused its driver's answer (2) before the abort it causes
    assert graph_status({**ok, NODE_SIM: 3, bv: 2}, {bv: "refused its driver's answer"}, False) == 2
    # the recorder could not write (5); the simulation, stopped, had to be SIGKILLed: still 5
    assert graph_status({**ok, NODE_SIM: -9, NODE_EVAL: 5},
                        {NODE_EVAL: "could not write its output", NODE_SIM: "did not end"}, False, [NODE_SIM]) == 5
    # the evaluator killed: the simulation, stopped, ends interrupted (130): 4
    assert graph_status({**ok, NODE_SIM: 130, NODE_EVAL: -9}, {NODE_EVAL: killed}, False, [NODE_EVAL]) == 4
    assert graph_status({**ok, NODE_SIM: 130}, {}, True) == 130


# --------------------------------------------------------------------------- Ctrl-C, a dead recorder


def test_sigint_to_launcher_leaves_finished_bag(tmp_path):
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--out", out, settle_s=0.3) as launcher:
        launcher.send_signal(signal.SIGINT)  # the launcher only: it forwards to the simulation node
        stdout, stderr = launcher.communicate(timeout=90)
    assert launcher.returncode == 130, f"exit status {launcher.returncode}\n{stdout}\n{stderr}"
    assert "Traceback" not in stderr and not _error_lines(stderr), stderr
    _assert_clean_terminal(stdout, stderr, out)
    bag_dir = out / "bag"
    assert f"interrupted: the bag {bag_dir} is finished" in stderr.splitlines(), stderr
    assert (bag_dir / "metadata.yaml").is_file()
    bag = _read_bag(bag_dir)
    assert _mcap_summary_count(bag_dir) == sum(len(v) for v in bag.values())
    events = _events(bag)
    ends = [(t, ev) for t, ev in events if ev["name"] == "evoscen/run_end"]
    assert len(ends) == 1 and ends[0][1]["kind"] == "interrupted", ends
    assert ends[0] == events[-1], "run_end is not the last event"
    k = ends[0][0] // DT_NS
    assert 0 < k < 5000
    for topic in PER_STEP_STATE:
        assert sorted(set(_steps(_stamps(bag, topic)))) == list(range(k + 1)), topic
    for topic in (*BV_TOPICS, "/evoscen/commands/sut"):
        assert set(range(k)) <= set(_steps(_stamps(bag, topic))) <= set(range(k + 1)), topic
    assert not [ev for _, ev in events if ev["name"] == "evoscen/fault"]
    # every node ended by itself (nothing had to be killed)
    assert NODES_LINE + "130" in stdout, stdout


def test_killed_recorder_is_one_error_line(tmp_path):
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--out", out) as launcher:
        ev = _children(launcher, "evoscen_eval.eval_node")
        assert len(ev) == 1, ev
        os.kill(ev[0], signal.SIGKILL)
        _stdout, stderr = launcher.communicate(timeout=90)
    assert launcher.returncode not in (0, 1), f"exit status {launcher.returncode}\n{stderr}"
    _assert_clean_terminal(_stdout, stderr, out)
    errors = _error_lines(stderr)
    assert len(errors) == 1 and errors[0].startswith("error: graph: node evoscen_eval ended early (killed by SIGKILL"), errors
    # what to do about the bag, on a line of its own (not a second error)
    assert re.search(rf"^the bag is not readable .*python scripts/reindex.py {re.escape(str(out / 'bag'))}$", stderr,
                     re.M), stderr


# --------------------------------------------------------------------------- bad parameters


def _node_with_params(domain: int, module: str, params_file: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", module, "--ros-args", "--params-file", str(params_file), *extra],
                            cwd=REPO, env=_node_env(domain), text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def test_bad_node_parameters_are_one_line_errors(tmp_path, own_domain):
    from evoscen_bringup.graph_runner import GraphOptions, write_parameter_files
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": 50, "bvs.nodes": "single"})  # the BV node under its plain name
    files = write_parameter_files(cfg, tmp_path, tmp_path / "bag", GraphOptions())

    def edit(node: str, change) -> Path:
        doc = yaml.safe_load(files[node].read_text())
        change(doc[node]["ros__parameters"])
        path = tmp_path / f"bad_{node}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        return path

    bad_bv = edit("evoscen_bv", lambda p: p["scenario"]["bvs"].__setitem__("count", -1))
    bad_sim = edit("evoscen_sim", lambda p: p.__setitem__("deadline_s", -1))
    cases = {  # started together: each takes a few seconds to start
        "model": _node_with_params(own_domain, "evoscen_sut.sut_node", files["evoscen_sut"], "-p", "model:=nosuch"),
        "bvs.count": _node_with_params(own_domain, "evoscen_bv.bv_node", bad_bv),
        "deadline_s": _node_with_params(own_domain, "evoscen_sim.nodes.sim_node", bad_sim),
    }
    results = {}
    try:
        for name, proc in cases.items():
            results[name] = (*proc.communicate(timeout=60), proc.returncode)
    finally:
        for proc in cases.values():
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    for name, (_out, err, rc) in results.items():
        lines = [line for line in err.splitlines() if line.strip()]
        assert rc == 2, f"{name}: exit status {rc}\n{err}"
        assert len(lines) == 1 and lines[0].startswith("error: "), f"{name}: expected one 'error:' line:\n{err}"
        results[name] = lines[0]
    model = results["model"]
    assert "'model'" in model and "nosuch" in model, model
    assert all(choice in model for choice in ("level0", "mobil", "nilsson", "stackelberg")), model
    assert "bvs.count" in results["bvs.count"] and "-1" in results["bvs.count"], results["bvs.count"]
    assert "evoscen_bv" in results["bvs.count"]
    assert "'deadline_s'" in results["deadline_s"] and "evoscen_sim" in results["deadline_s"], results["deadline_s"]
    assert results["deadline_s"].startswith(f"error: {bad_sim}: key 'deadline_s' = -1: expected a number > 0 (node evoscen_sim, line ")


_BAD_OWN = {  # node -> (module, [(key, wrong type, expected), (key, out of range, expected)])
    "evoscen_sim": ("evoscen_sim.nodes.sim_node", [("max_misses", "five", "expected an integer >= 1"),
                                             ("deadline_s", -1, "expected a number > 0")]),
    "evoscen_bv": ("evoscen_bv.bv_node", [("startup_timeout_s", "soon", "expected a number > 0"),
                                          ("discovery_settle_s", -0.5, "expected a number >= 0")]),
    "evoscen_sut": ("evoscen_sut.sut_node", [("model", 5, "expected one of "), ("model", "nosuch", "expected one of ")]),
    "evoscen_eval": ("evoscen_eval.eval_node", [("nice", True, "expected an integer in [0, 19]"),
                                                ("nice", 25, "expected an integer in [0, 19]")]),
}


@pytest.mark.parametrize("node", sorted(_BAD_OWN))
def test_bad_own_parameter_is_one_line_naming_file_key_value_expected(tmp_path, node, own_domain):
    """A node's own parameter of the wrong type, and one out of range: exit 2 and exactly one
    line ``error: <file>: key '<key>' = <value>: <expected> (node <node>, line <n>)``, the
    format of a bad scenario key (one validator, evoscen_sim.config.config_load.build)."""
    from evoscen_bringup.graph_runner import GraphOptions, write_parameter_files
    from evoscen_sim.config.scenario_config import load_scenario_config

    files = write_parameter_files(load_scenario_config(None, {"steps": 20, "bvs.nodes": "single"}), tmp_path, tmp_path / "bag", GraphOptions())
    module, cases = _BAD_OWN[node]
    procs, wanted = [], []
    for i, (key, value, expected) in enumerate(cases):
        doc = yaml.safe_load(files[node].read_text())
        doc[node]["ros__parameters"][key] = value
        path = tmp_path / f"bad_{i}.yaml"
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        line = next(n for n, text in enumerate(path.read_text().splitlines(), 1) if text.startswith(f"    {key}:"))
        wanted.append((f"error: {path}: key '{key}' = {value!r}: {expected}", f"(node {node}, line {line})"))
        procs.append(_node_with_params(own_domain, module, path))
    try:
        results = [(*proc.communicate(timeout=60), proc.returncode) for proc in procs]
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    for (start, end), (_out, err, rc) in zip(wanted, results):
        lines = [line for line in err.splitlines() if line.strip()]
        assert rc == 2, f"exit status {rc}\n{err}"
        assert len(lines) == 1 and lines[0].startswith(start) and lines[0].endswith(end), (start, end, err)


def test_own_parameters_name_the_node_or_the_command_line(monkeypatch):
    """Without a parameter file the error names the node; a ``-p`` value the command line."""
    from evoscen_contract import graph
    from evoscen_sim.errors import InputError
    from evoscen_sim.nodes.node_params import own_parameters
    from evoscen_sim.nodes.sim_node import SimParams

    monkeypatch.setattr(graph, "_init_args", ["sim"])
    own = own_parameters(SimParams, {"scenario": {}, "use_sim_time": False, "deadline_s": 3}, "evoscen_sim")
    assert (own.deadline_s, own.max_misses, own.controllers) == (3.0, 5, ())  # (): the scenario's BV nodes and the SUT
    with pytest.raises(InputError) as exc:
        own_parameters(SimParams, {"controllers": ["evoscen_bv", "evoscen_bv"]}, "evoscen_sim")
    assert str(exc.value) == ("evoscen_sim: key 'controllers' = ['evoscen_bv', 'evoscen_bv']: expected a "
                              "list of distinct non-empty node names")
    monkeypatch.setattr(graph, "_init_args", ["sim", "--ros-args", "--params-file", "/nonexistent.yaml",
                                              "-p", "wait_for_nodes:=['']"])
    with pytest.raises(InputError) as exc:
        own_parameters(SimParams, {"wait_for_nodes": [""]}, "evoscen_sim")
    assert str(exc.value) == ("command line: key 'wait_for_nodes' = ['']: expected a list of non-empty node "
                              "names (node evoscen_sim)")
    with pytest.raises(InputError) as exc:  # a required parameter left out: its default fails
        own_parameters(__import__("evoscen_eval.eval_node").eval_node.EvalParams, {}, "evoscen_eval")
    assert str(exc.value) == ("/nonexistent.yaml: key 'bag_dir' = '' (default): expected a non-empty string "
                              "(node evoscen_eval)")


def test_scenario_parameters_name_the_parameter_file(monkeypatch):
    """A bad ``scenario.*`` parameter: the scenario validator's one line, naming the node's
    parameter file (the last one given) and the node; without a file, the node."""
    from evoscen_contract import graph
    from evoscen_sim.errors import InputError
    from evoscen_sim.nodes.node_params import scenario_from_node

    monkeypatch.setattr(graph, "_init_args", ["sim", "--ros-args", "--params-file", "/a.yaml", "--params-file",
                                              "/b.yaml"])
    with pytest.raises(InputError) as exc:
        scenario_from_node({"scenario": {"steps": -1}}, "evoscen_sim")
    assert str(exc.value) == ("/b.yaml (node evoscen_sim, scenario.*): key 'steps' = -1: expected an integer in "
                              "[1, 1000000]")
    monkeypatch.setattr(graph, "_init_args", ["sim"])
    with pytest.raises(InputError) as exc:
        scenario_from_node({"scenario": {"seed": "x"}}, "evoscen_bv")
    assert str(exc.value).startswith("evoscen_bv parameter 'scenario': key 'seed' = 'x': expected ")


def test_no_bvs_graph_bag_equals_inprocess_bag(tmp_path):
    """``bvs.count: 0``: the graph starts no BV controller, the in-process runner writes no BV
    commands either (it wrote one empty table per step): the two bags are byte-identical."""
    config = tmp_path / "no_bvs.yaml"
    config.write_text("bvs: {count: 0}\nspawn: {ramp_vehicles: 0}\n")
    graph = _run_cli("--mode", "graph", "--config", config, "--steps", 30, "--seed", 2, "--out", tmp_path / "graph")
    assert graph.returncode == 0, graph.stderr
    inproc = _run_cli("--mode", "inprocess", "--config", config, "--steps", 30, "--seed", 2, "--out",
                      tmp_path / "inproc", "--quiet", "--no-plots")
    assert inproc.returncode == 0, inproc.stderr
    g_dir, i_dir = tmp_path / "graph" / "bag", tmp_path / "inproc" / "bag"
    g, i = _read_bag(g_dir), _read_bag(i_dir)
    assert "/evoscen/commands/bv" not in g and "/evoscen/commands/bv" not in i
    assert _steps(_stamps(i, "/evoscen/commands/sut")) == list(range(30))
    assert (g_dir / "metadata.yaml").read_bytes() == (i_dir / "metadata.yaml").read_bytes(), "metadata.yaml differs"
    assert (g_dir / "bag_0.mcap").read_bytes() == (i_dir / "bag_0.mcap").read_bytes(), "bag_0.mcap differs"


def test_challenge_graph_bag_equals_inprocess_bag(tmp_path):
    """``challenge.mode: nade`` (docs/challenges.md): the layer runs in the simulation, so the graph and the
    in-process runner record the same bytes, its onsets and the run's weight included (seed 990004 has two
    onsets in 300 steps; 150 steps hold the first)."""
    config = tmp_path / "nade.yaml"
    config.write_text("challenge: {mode: nade}\n")
    args = ("--config", config, "--sut", "mobil", "--steps", 150, "--seed", 990004)
    graph = _run_cli("--mode", "graph", *args, "--out", tmp_path / "graph")
    assert graph.returncode == 0, graph.stderr
    inproc = _run_cli("--mode", "inprocess", *args, "--out", tmp_path / "inproc", "--quiet", "--no-plots")
    assert inproc.returncode == 0, inproc.stderr
    g_dir, i_dir = tmp_path / "graph" / "bag", tmp_path / "inproc" / "bag"
    assert (g_dir / "bag_0.mcap").read_bytes() == (i_dir / "bag_0.mcap").read_bytes(), "bag_0.mcap differs"
    report = json.loads((tmp_path / "graph" / "report" / "report.json").read_text(encoding="utf-8"))
    assert report["challenge"]["count"] >= 1 and report["challenge"]["complete"]
