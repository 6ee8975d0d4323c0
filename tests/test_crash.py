"""Faults in a running node graph: killed, terminated and stalled nodes (docs/recording.md).

* SIGTERM to the evaluator mid-run: it finishes the bag (summary + metadata.yaml), every step it
  received is in it; the launcher names the node and exits 4;
* SIGKILL to the evaluator (the lockstep frozen first, so the steps published are known): the bag
  is reindexed by ``scripts/reindex.py`` and loses at most ~1 s of simulated time;
* SIGKILL to the simulation node: the graph ends within 10 s, exit 4 naming the node;
* SIGKILL to a controller during start-up: the graph ends within 10 s, exit 4 naming it;
* the evaluator stalled (SIGSTOP) beyond what killed a controller before (~10 s): the run
  completes, nothing lost.

Only processes started by a test are signalled (children of its own launcher).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the graph tests' helpers
from test_graph import BV_TOPICS, PER_STEP_STATE, REPO, _assert_clean_terminal, _children, _error_lines, _events, \
    _launch, _mcap_summary_count, _node_logs, _read_bag, _running, _stamps, _steps, _terminate

pytestmark = [pytest.mark.e2e, pytest.mark.filterwarnings("ignore::DeprecationWarning")]


def _lockstep_steps(out: Path) -> int:
    """The steps the simulation node says it published, from its log file."""
    log = _node_logs(out)["evoscen_sim"]
    m = re.search(r"evoscen_sim: lockstep: (\d+) steps", log)
    assert m, log
    return int(m.group(1))


def _world_steps(bag_dir: Path) -> list[int]:
    return _steps(_stamps(_read_bag(bag_dir), "/evoscen/world"))


def test_sigterm_to_evaluator_finishes_the_bag(tmp_path):
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--out", out, "--no-plots", settle_s=0.5) as launcher:
        ev = _children(launcher, "evoscen_eval.eval_node")
        assert len(ev) == 1, ev
        os.kill(ev[0], signal.SIGTERM)
        t_kill = time.monotonic()
        stdout, stderr = launcher.communicate(timeout=60)
        after = time.monotonic() - t_kill
    print(f"\nevaluator SIGTERM: graph ended {after:.1f} s later")
    assert launcher.returncode == 4, f"{launcher.returncode}\n{stdout}\n{stderr}"
    logs = _assert_clean_terminal(stdout, stderr, out)
    assert after < 10.0
    errors = _error_lines(stderr)
    assert len(errors) == 1 and "evoscen_eval" in errors[0], errors
    assert re.search(r"^evoscen_eval: SIGTERM: bag finished with \d+ messages$", logs["evoscen_eval"], re.M), logs
    bag_dir = out / "bag"
    assert (bag_dir / "metadata.yaml").is_file()
    bag = _read_bag(bag_dir)
    assert _mcap_summary_count(bag_dir) == sum(len(v) for v in bag.values())
    # every step received up to the end, in order; the last step may be partial (its world table
    # not yet in when SIGTERM came, its odometry already): the bag holds what was received
    per_topic = {topic: _steps(_stamps(bag, topic)) for topic in PER_STEP_STATE}
    k = min(len(v) for v in per_topic.values())
    assert k > 10
    for topic, steps in per_topic.items():
        # contiguous from step 0 on every topic; where each topic stops differs by what had arrived
        # (seen: odometry 5 steps ahead of the larger world table when SIGTERM came)
        assert steps == list(range(len(steps))), topic
    from rosbags.rosbag2 import Reader

    with Reader(bag_dir) as reader:
        assert reader.message_count == sum(len(v) for v in bag.values())


def test_sigkill_to_evaluator_then_reindex_loses_at_most_a_second(tmp_path):
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--out", out, "--no-plots", settle_s=1.0) as launcher:
        sim = _children(launcher, "evoscen_sim.nodes.sim_node")
        ev = _children(launcher, "evoscen_eval.eval_node")
        assert len(sim) == 1 and len(ev) == 1, (sim, ev)
        os.kill(sim[0], signal.SIGSTOP)  # freeze the lockstep: the steps published are known
        time.sleep(1.5)  # the recorder takes and writes all it can
        os.kill(ev[0], signal.SIGKILL)
        time.sleep(0.3)
        os.kill(sim[0], signal.SIGCONT)
        stdout, stderr = launcher.communicate(timeout=60)
    assert launcher.returncode == 4, f"{launcher.returncode}\n{stdout}\n{stderr}"
    _assert_clean_terminal(stdout, stderr, out)
    errors = _error_lines(stderr)
    assert len(errors) == 1 and "evoscen_eval" in errors[0] and "SIGKILL" in errors[0], stderr
    assert any("reindex.py" in line for line in stderr.splitlines()), stderr  # what to do, on a line of its own
    published = _lockstep_steps(out)  # the run went on for a step or two after SIGCONT at most
    bag_dir = out / "bag"
    res = subprocess.run([sys.executable, "scripts/reindex.py", bag_dir], cwd=REPO, capture_output=True, text=True,
                         timeout=120, check=False)
    assert res.returncode == 0, res.stderr
    steps = _world_steps(bag_dir)
    assert steps == list(range(len(steps)))
    lost = published - steps[-1]
    print(f"\nevaluator SIGKILL: {published} steps published, {steps[-1]} recorded, {lost} lost; {res.stdout}")
    # what the recorder lost is at most its open chunk (10 steps = 1 s); what this test can count
    # also holds the steps the simulation made after SIGCONT, before the launcher's stop took
    # effect: usually one or two, but the stop signal is sometimes acted on only seconds later
    # (measured; docs/recording.md), and then the flow control (recorder_lag_steps = 50: the
    # simulation waits for the dead recorder's acknowledgements) bounds the run-on
    assert 0 <= lost <= 10 + 50 + 2, f"lost {lost} steps (> 1 s of simulated time + the flow-control window)"
    from rosbags.rosbag2 import Reader

    with Reader(bag_dir) as reader:
        assert reader.message_count == _mcap_summary_count(bag_dir)
    ev = subprocess.run([sys.executable, "scripts/evaluate.py", bag_dir, "--no-plots", "--out", tmp_path / "rep"],
                        cwd=REPO, capture_output=True, text=True, timeout=120, check=False)
    assert ev.returncode == 0 and "Traceback" not in ev.stderr, ev.stderr


def _assert_quick_end(launcher: subprocess.Popen, node: str, t_kill: float, out: Path, timeout: float = 60) -> str:
    stdout, stderr = launcher.communicate(timeout=timeout)
    after = time.monotonic() - t_kill
    print(f"\n{node} killed: graph ended {after:.1f} s later, status {launcher.returncode}")
    assert launcher.returncode == 4, f"{launcher.returncode}\n{stdout}\n{stderr}"
    assert after <= 10.0, f"the graph took {after:.1f} s to end"
    _assert_clean_terminal(stdout, stderr, out)
    errors = _error_lines(stderr)
    assert len(errors) == 1 and node in errors[0] and "SIGKILL" in errors[0], errors
    assert errors[0].endswith(f" (node logs: {out / 'logs'}/)"), errors
    return stderr


def test_killed_simulation_node_ends_the_graph_quickly(tmp_path):
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", 5000, "--seed", 5, "--out", out, "--no-plots", settle_s=0.5) as launcher:
        sim = _children(launcher, "evoscen_sim.nodes.sim_node")
        os.kill(sim[0], signal.SIGKILL)
        t_kill = time.monotonic()
        _assert_quick_end(launcher, "evoscen_sim", t_kill, out)
    bag = _read_bag(out / "bag")  # the evaluator finished the bag on the launcher's SIGTERM
    assert _mcap_summary_count(out / "bag") == sum(len(v) for v in bag.values())


def test_kill_during_startup_ends_the_graph_quickly(tmp_path):
    out = tmp_path / "run"
    launcher = _launch("--steps", 500, "--seed", 5, "--out", out, "--no-plots")
    try:
        end = time.monotonic() + 30
        while not _children(launcher, "evoscen_sut.sut_node") and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.5)  # the nodes are starting (importing, discovering): no step yet
        assert not (out / "params" / ".evoscen_sim.ready").exists(), "start-up was already over"
        sut = _children(launcher, "evoscen_sut.sut_node")
        assert len(sut) == 1, sut
        os.kill(sut[0], signal.SIGKILL)
        t_kill = time.monotonic()
        stderr = _assert_quick_end(launcher, "evoscen_sut", t_kill, out)
    finally:
        _terminate(launcher)
    assert "during start-up" in stderr, stderr


def test_stalled_recorder_kills_nothing_and_loses_nothing(tmp_path):
    # before: ~10 s killed a controller ("Failed to publish"); with flow control but the default 20 s
    # participant lease, a stall beyond 20 s unmatched the recorder and the lockstep ran on (data
    # lost); 25 s fails on both. 30 s measured by hand (docs/recording.md).
    stall_s = float(os.environ.get("EVOSCEN_STALL_S", "25"))
    steps = 3000
    out = tmp_path / "run"
    with _running(out / "bag", "--steps", steps, "--seed", 5, "--out", out, "--no-plots", settle_s=0.3) as launcher:
        ev = _children(launcher, "evoscen_eval.eval_node")
        assert len(ev) == 1, ev
        os.kill(ev[0], signal.SIGSTOP)
        time.sleep(stall_s)
        os.kill(ev[0], signal.SIGCONT)
        stdout, stderr = launcher.communicate(timeout=120)
    assert launcher.returncode == 0, f"{launcher.returncode}\n{stdout}\n{stderr}"
    assert not _error_lines(stderr), stderr
    _assert_clean_terminal(stdout, stderr, out)
    bag = _read_bag(out / "bag")
    for topic in PER_STEP_STATE:
        assert _steps(_stamps(bag, topic)) == list(range(steps + 1)), topic
    for topic in (*BV_TOPICS, "/evoscen/commands/sut"):
        assert _steps(_stamps(bag, topic)) == list(range(steps)), topic
    assert not [ev for _, ev in _events(bag) if ev["name"] == "evoscen/fault"]
