"""evoscen_experiments.bench_graph: which process is which node, its CPU time from /proc, and the
per-step difference of two runs (``scripts/bench.py --node-cpu``)."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from evoscen_experiments.bench_graph import NodeCpuSampler, node_cpu_seconds, node_key, per_step_us


@pytest.mark.parametrize("argv, key", [
    (["python", "-m", "evoscen_bv.bv_node", "--ros-args", "-r", "__node:=evoscen_bv_mutual"], "evoscen_bv_mutual"),
    (["python", "-m", "evoscen_sim.nodes.sim_node", "--ros-args", "--params-file", "p.yaml"], "evoscen_sim"),
    (["python", "-m", "evoscen_sut.sut_node"], "evoscen_sut"),
    (["python", "-m", "evoscen_eval.eval_node"], "evoscen_eval"),
    (["python", "-m", "pytest", "-q"], None),
    (["python", "-m", "evoscen_eval.scoring.report"], None),  # a module of ours that is not a node
    (["bash", "-c", "sleep 1"], None),
    ([], None)])
def test_node_key(argv, key):
    assert node_key(argv) == key


def test_per_step_us_is_the_difference_of_two_runs():
    # start-up 2.0 s in both; 0.5 ms a step: 1,000 steps -> 2.5 s, 5,000 -> 4.5 s: (4.5 - 2.5) / 4,000 = 500 us
    short, long = {"evoscen_sim": 2.5, "evoscen_bv": 1.2}, {"evoscen_sim": 4.5, "evoscen_bv": 2.0}
    us = per_step_us(short, long, 1000, 5000)
    assert us == pytest.approx({"evoscen_sim": 500.0, "evoscen_bv": 200.0})
    assert per_step_us({}, {"evoscen_sut": 0.4}, 100, 500) == pytest.approx({"evoscen_sut": 1000.0})
    with pytest.raises(ValueError, match="more steps"):
        per_step_us(short, long, 5000, 5000)


BUSY = ("import time\n"
        "while time.process_time() < 0.3:\n"
        "    pass\n"
        "time.sleep(30)\n")
LOW = 0.3 - 2 / os.sysconf("SC_CLK_TCK")  # /proc counts whole clock ticks (10 ms), each of utime and stime cut


def test_a_child_node_is_found_with_its_cpu_time():
    # a child process named like a BV node that burns 0.3 s of CPU, then sleeps
    child = subprocess.Popen([sys.executable, "-c", BUSY, "--ros-args", "-r", "__node:=evoscen_bv_test"])
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            found = node_cpu_seconds(os.getpid())
            if child.pid in found and found[child.pid][1] >= LOW:
                break
            time.sleep(0.05)
        assert found[child.pid][0] == "evoscen_bv_test"
        assert LOW <= found[child.pid][1] < 3.0  # its busy loop, plus the interpreter's start-up
        assert all(key == "evoscen_bv_test" for key, _ in found.values())  # nothing else of ours runs
        with NodeCpuSampler(period_s=0.01) as sampler:
            time.sleep(0.1)
        assert LOW <= sampler.seconds["evoscen_bv_test"] < 3.0
    finally:
        child.kill()
        child.wait()
