"""A driver plug-in that fails, and the plug-in face that lasts (docs/plugins.md §3, §19; docs/recording.md).

* A model whose ``act`` raises: one ``error:`` line naming the model, the step, the exception and the
  plug-in's file:line, exit status 3, no traceback, a finished bag ending ``aborted``, no score — in
  process (a model registered in this process) and in the node graph (an entry point in a directory on
  PYTHONPATH: a ``*.dist-info`` with ``entry_points.txt`` is all ``importlib.metadata`` needs), where
  the run ends within 2 s of the failed step although the deadline is 10 s; the graph's terminal holds
  the same line, naming the node logs (the nodes' own lines are there), and no node's log line.
* A factory that raises: the same line and status before anything runs.
* ``run_scenario.py --list-suts`` / ``--list-mutants``.
* The face: its names pinned; the examples import evoscen from it alone; a 0.4 import path works with a
  DeprecationWarning naming the new one.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "run_scenario.py"
FAIL_STEP = 3
"""The step at whose ``act`` the in-process test model raises."""


class _Raising:
    """A SUT driver: keeps its lane at zero throttle, then divides by zero at step FAIL_STEP."""

    def __init__(self, vehicles):
        self.vehicles = vehicles

    def act(self, view):
        if view.step_index == FAIL_STEP:
            return 1 / 0  # the failing line the error must name
        return np.zeros(len(self.vehicles)), np.zeros(len(self.vehicles), dtype=np.int64)


RAISING_LINE = next(i for i, line in enumerate(Path(__file__).read_text().splitlines(), 1)
                    if "return 1 / 0" in line)


def _factory_raises(vehicles, params, config, rng):
    raise KeyError("no_such_setting")


def _run_cli_here(argv: list[str], capsys) -> tuple[int, str, str]:
    """``scripts/run_scenario.py``'s ``main(argv)`` in this process (sees in-process registrations)."""
    sys.path.insert(0, str(REPO / "scripts"))
    try:
        import run_scenario
    finally:
        sys.path.remove(str(REPO / "scripts"))
    capsys.readouterr()
    code = run_scenario.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def registered():
    from evoscen import ModelSpec, register_model, unregister_model

    register_model(ModelSpec("raising_sut", ("sut",), lambda v, p, c, r: _Raising(v), description="raises"))
    register_model(ModelSpec("unbuildable_sut", ("sut",), _factory_raises, description="cannot be built"))
    yield
    unregister_model("raising_sut")
    unregister_model("unbuildable_sut")


def _bag_events(bag_dir: Path) -> list[dict]:
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_contract.topics import parse_events
    from evoscen_record.bag_reader import open_bag_reader
    from rclpy.serialization import deserialize_message

    return [ev for topic, _type, _t, data in open_bag_reader(bag_dir) if topic == "/evoscen/events"
            for ev in parse_events(deserialize_message(data, DiagnosticArray))]


def test_act_raising_in_process_is_one_line_status_3(registered, tmp_path, capsys):
    out = tmp_path / "run"
    code, stdout, stderr = _run_cli_here(["--mode", "inprocess", "--sut", "raising_sut", "--steps", "20", "--bvs", "3",
                                          "--out", str(out), "--quiet", "--no-plots", "--bag-writer", "inline"], capsys)
    assert code == 3, stderr
    assert "Traceback" not in stderr
    here = os.path.relpath(__file__)
    assert stderr.splitlines() == [
        f"error: sut model 'raising_sut': act() at step {FAIL_STEP} raised ZeroDivisionError: division by zero "
        f"({here}:{RAISING_LINE})"], stderr
    assert stdout.splitlines() == [
        f"aborted: the bag {out / 'bag'} is finished ({FAIL_STEP + 1} world states); the run is not scored"], stdout
    assert not (out / "report" / "report.json").exists()
    events = _bag_events(out / "bag")
    assert [e["name"] for e in events[-2:]] == ["evoscen/fault", "evoscen/run_end"], events[-2:]
    fault, end = events[-2:]
    assert (fault["kind"], fault["controller"], fault["step"]) == ("abort", "evoscen_sut", FAIL_STEP)
    assert "ZeroDivisionError" in fault["message"]
    assert end["kind"] == "aborted" and end["step"] == FAIL_STEP


def test_factory_raising_is_one_line_status_3(registered, tmp_path, capsys):
    code, stdout, stderr = _run_cli_here(["--mode", "inprocess", "--sut", "unbuildable_sut", "--steps", "5",
                                          "--out", str(tmp_path / "run"), "--quiet"], capsys)
    assert code == 3 and stdout == ""
    here = os.path.relpath(__file__)
    line = next(i for i, text in enumerate(Path(__file__).read_text().splitlines(), 1) if 'raise KeyError("no_such' in text)
    assert stderr.splitlines() == [f"error: sut model 'unbuildable_sut': its factory raised KeyError: 'no_such_setting' "
                                   f"({here}:{line})"], stderr
    assert not (tmp_path / "run").exists()  # failed before the output was touched


def test_list_suts_and_mutants(registered, capsys):
    code, stdout, _ = _run_cli_here(["--list-suts"], capsys)
    assert code == 0
    rows = {line.split()[0]: line for line in stdout.splitlines()}
    assert {"mobil", "nilsson", "stackelberg", "mutant", "level0", "raising_sut"} <= set(rows)
    assert re.fullmatch(r"mobil +built-in \(evoscen_sut\) +MOBIL lane changes .*", rows["mobil"]), rows["mobil"]
    assert re.fullmatch(r"raising_sut +registered in this process \((tests\.)?test_plugin_faults\) +raises", rows["raising_sut"])
    code, stdout, _ = _run_cli_here(["--list-mutants"], capsys)
    from evoscen_sut.mutants import LIBRARY

    lines = stdout.splitlines()
    assert code == 0 and [line.split()[0] for line in lines] == list(LIBRARY)
    # the bases each mutant states (docs/mutants.md): a control defect applies to every base, a
    # lane-change defect not to the lane keeper level0
    # the example plug-ins are bases where installed (make setup installs both; make test-core may not)
    plugins = "".join(f", {p}" for p in ("fiss", "sumo_sut") if p in rows)
    assert re.fullmatch(r"weak_braking +built-in \(evoscen_sut\.mutants\) +control +"
                        rf"bases: level0, mobil, nilsson, stackelberg{plugins} +"
                        r"Braking commands reach the wheels at 40 % \(worn brakes / saturated actuator\)",
                        lines[list(LIBRARY).index("weak_braking")]), lines
    assert re.fullmatch(rf"frozen +built-in \(evoscen_sut\.mutants\) +decision +bases: mobil, nilsson, stackelberg{plugins}"
                        r" +.*", lines[list(LIBRARY).index("frozen")]), lines


# ------------------------------------------------------------------ the node graph

PLUGIN = textwrap.dedent('''
    import numpy as np
    from evoscen import ModelSpec


    class Diverging:
        def __init__(self, vehicles):
            self.vehicles = vehicles

        def act(self, view):
            if view.step_index == 30:
                raise RuntimeError("planner diverged")
            return np.zeros(1), np.zeros(1, dtype=np.int64)


    SPEC = ModelSpec("diverging_sut", ("sut",), lambda v, p, c, r: Diverging(v), description="raises at step 30")
''')
PLUGIN_LINE = next(i for i, line in enumerate(PLUGIN.splitlines(), 1) if "raise RuntimeError" in line)


def _plugin_site(tmp_path: Path) -> dict[str, str]:
    """The environment of a process that sees the plug-in PLUGIN through an entry point (a ``*.dist-info``
    with ``entry_points.txt`` in a directory on PYTHONPATH)."""
    site = tmp_path / "site"
    (site / "diverging_sut-0.1.dist-info").mkdir(parents=True)
    (site / "diverging_sut.py").write_text(PLUGIN)
    (site / "diverging_sut-0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: diverging-sut\nVersion: 0.1\n")
    (site / "diverging_sut-0.1.dist-info" / "entry_points.txt").write_text("[evoscen.sut]\ndiverging_sut = diverging_sut:SPEC\n")
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), *(p for p in sys.path if p)]))


RAW_LOG_LINE = re.compile(r"^\[(WARN|ERROR|INFO|DEBUG|FATAL)\] \[\d+\.\d+\]", re.M)
"""A line of rclpy's console logger (a node's, for its log file)."""
PLUGIN_ERROR = (r"sut model 'diverging_sut' \(entry point diverging_sut:SPEC\): act\(\) at step 30 raised "
                rf"RuntimeError: planner diverged \(.*diverging_sut\.py:{PLUGIN_LINE}\)")


@pytest.fixture(scope="module")
def raising_in_the_graph(tmp_path_factory):
    """``--mode graph`` with the plug-in that raises at step 30 (deadline 10 s, 5 misses: waiting out the
    deadlines would take 50 s), as a person runs it: its terminal (stdout, stderr) and its output."""
    tmp = tmp_path_factory.mktemp("graph_fault")
    env = _plugin_site(tmp)
    out = tmp / "run"
    res = subprocess.run([sys.executable, str(SCRIPT), "--sut", "diverging_sut", "--steps", "60", "--bvs", "3",
                          "--deadline", "10", "--out", str(out), "--no-plots"], cwd=REPO, env=env, text=True,
                         capture_output=True, timeout=240, check=False)
    return {"res": res, "out": out, "env": env, "tmp": tmp}


@pytest.mark.e2e
def test_act_raising_in_the_graph_is_one_line_naming_the_node_logs(raising_in_the_graph):
    res, out = raising_in_the_graph["res"], raising_in_the_graph["out"]
    terminal = res.stdout + res.stderr
    assert res.returncode == 3, terminal
    errors = [line for line in terminal.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and re.fullmatch(rf"error: {PLUGIN_ERROR} \(node logs: {re.escape(str(out / 'logs'))}/\)",
                                             errors[0]), terminal
    assert not RAW_LOG_LINE.search(terminal) and "Traceback" not in terminal, terminal
    # the launcher's lines only: where things are, then the summary (stdout)
    assert [line for line in res.stderr.splitlines() if not line.startswith(("graph: ", "error: "))] == [], res.stderr
    assert "comparative score" not in res.stdout and "intelligence" not in res.stdout
    assert "aborted: the run ended at step 30 of 60 (exit status 3)" in res.stdout
    # the nodes' own lines are in their log files: the SUT node's error, the simulation's rclpy warning
    sut = (out / "logs" / "evoscen_sut.log").read_text()
    assert re.fullmatch(rf"error: {PLUGIN_ERROR}\n", sut), sut
    sim = (out / "logs" / "evoscen_sim.log").read_text()
    assert re.search(r"^\[WARN\] \[\d+\.\d+\] \[evoscen_sim\]: controller 'evoscen_sut' ended before answering "
                     "step 30", sim, re.M), sim
    assert not (out / "report" / "report.json").exists()
    events = _bag_events(out / "bag")
    fault, end = events[-2:]
    assert (fault["name"], fault["kind"], fault["controller"], fault["step"]) == ("evoscen/fault", "abort", "evoscen_sut", 30)
    assert (end["name"], end["kind"]) == ("evoscen/run_end", "aborted")


@pytest.mark.e2e
def test_act_raising_in_the_graph_ends_within_2_s(raising_in_the_graph):
    """The launcher tells the simulation at once: the graph ends within 2 s of the SUT node's end (the
    launcher's log: when it saw the node end, when the graph had ended), not after 5 deadlines of 10 s."""
    log = (raising_in_the_graph["out"] / "logs" / "launcher.log").read_text()
    failed = re.search(r"^ *(\d+\.\d) s  evoscen_sut ended with a controller fault \(exit status 3\)$", log, re.M)
    ended = re.search(r"^ *(\d+\.\d) s  ended: exit status 3; ", log, re.M)
    assert failed and ended, log
    took = float(ended.group(1)) - float(failed.group(1))
    print(f"\nthe graph ended {took:.1f} s after the SUT node's fault (os.getloadavg: {os.getloadavg()[0]:.1f})")
    assert took < 2.0, log


@pytest.mark.e2e
def test_act_raising_is_the_same_line_in_both_runners(raising_in_the_graph):
    """The in-process runner's one line for the same plug-in and step is the graph's, less where its node logs are."""
    tmp = raising_in_the_graph["tmp"]
    res = subprocess.run([sys.executable, str(SCRIPT), "--mode", "inprocess", "--sut", "diverging_sut", "--steps", "60",
                          "--bvs", "3", "--out", str(tmp / "inprocess"), "--no-plots", "--quiet"], cwd=REPO,
                         env=raising_in_the_graph["env"], text=True, capture_output=True, timeout=240, check=False)
    assert res.returncode == 3, res.stderr
    graph = [line for line in raising_in_the_graph["res"].stderr.splitlines() if line.startswith("error:")]
    assert res.stderr.splitlines() == [graph[0].split(" (node logs: ")[0]], (res.stderr, graph)


# ------------------------------------------------------------------ the face

def test_examples_import_evoscen_only_from_the_face():
    files = sorted((REPO / "examples").rglob("*.py"))
    assert len(files) >= 4
    seen = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for name in names:
                if name.startswith("evoscen"):
                    seen.append((path.name, name))
    assert seen and all(module == "evoscen" for _, module in seen), seen
    assert {"first_sut.py", "fiss_sut.py", "sumo_sut.py"} <= {f for f, _ in seen}


def test_every_moved_path_resolves():
    """Every 0.6 path that moved (evoscen_sim.moved_paths) leads to a module that exists, in its own package
    or the one it moved to; the 0.5 generation of aliases is gone with 0.7.0."""
    import importlib.util

    from evoscen_sim import moved_paths

    assert moved_paths.ROOMS_MOVED_IN == "0.7.0" and moved_paths.ROOMS_REMOVED_IN == "0.8.0"
    assert not hasattr(moved_paths, "MOVED_MODULES") and not hasattr(moved_paths, "MOVED_NAMES")
    for new in moved_paths.ROOM_MODULES.values():
        assert importlib.util.find_spec(new) is not None, new
    for old in ("evoscen_sim.models", "evoscen_eval.testing", "evoscen_sim.world"):  # 0.4 paths: gone
        sys.modules.pop(old, None)
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(old)


def test_a_controller_fault_line_comes_before_the_abort_and_deaths():
    """graph_status (docs/recording.md): a controller that ended with its own fault line (3: its driver
    raised) is the cause of the simulation's abort (3) that follows; a kill (4) stays a death."""
    from evoscen_bringup.graph_runner import graph_status

    ok = {"evoscen_eval": 0, "evoscen_bv": 0}
    failed = {"evoscen_sut": "ended with a controller fault (exit status 3)"}
    assert graph_status({**ok, "evoscen_sut": 3, "evoscen_sim": 3}, failed, False) == 3
    # a BV node killed as well, after it: the first cause still decides
    assert graph_status({**ok, "evoscen_sut": 3, "evoscen_bv": -9, "evoscen_sim": 3},
                        {**failed, "evoscen_bv": "ended early (killed by SIGKILL (signal 9))"}, False, ["evoscen_bv"]) == 3
    assert graph_status({**ok, "evoscen_sut": -9, "evoscen_sim": 3},
                        {"evoscen_sut": "ended early (killed by SIGKILL (signal 9))"}, False, ["evoscen_sut"]) == 4
