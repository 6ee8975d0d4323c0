"""The node graph's figures of ``scripts/bench.py --mode graph``: the lockstep rate beside an in-process
run, the BV-node partitions, and each node's CPU time per step (docs/performance.md: its figures in the CHANGELOG).

A graph run's nodes are child processes of the launcher; :class:`NodeCpuSampler` reads their
CPU time (user + system, all threads) from ``/proc`` every ``period_s`` while the run goes, and
keeps the last reading of each, since a node's process is gone once the run ends. A node is
named by its ROS node name (``-r __node:=NAME``) or else by the package of its ``-m`` module
(``evoscen_sim``, ``evoscen_sut``, ``evoscen_eval``, ``evoscen_bv``).

A run's CPU time includes each node's start-up (imports, compiled kernels loaded, discovery),
seconds on a 2-core machine; :func:`per_step_us` takes the difference of two runs of different
lengths, which leaves the cost of the steps alone (docs/performance.md: its figures in the CHANGELOG).
"""

from __future__ import annotations

import json
import os
import statistics
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

PROC = Path("/proc")

INPROCESS_PER_GRAPH_STEP = 10
"""In-process steps timed beside each graph step (the in-process runner is ~10-20x faster)."""


def node_key(argv: list[str]) -> str | None:
    """The node a process's command line runs: its ``__node:=`` name, else the package of its
    ``-m evoscen_<pkg>.…`` module; None for any other process."""
    for arg in argv:
        if arg.startswith("__node:="):
            return arg.split(":=", 1)[1]
    for flag, module in zip(argv, argv[1:]):
        if flag == "-m" and module.startswith("evoscen_") and module.endswith("_node"):
            return module.split(".", 1)[0]
    return None


def _stat(pid: str) -> tuple[int, float] | None:
    """``(parent pid, CPU seconds)`` of a process, None if it is gone."""
    try:
        fields = (PROC / pid / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    ticks = os.sysconf("SC_CLK_TCK")
    return int(fields[1]), (int(fields[11]) + int(fields[12])) / ticks  # ppid, utime + stime


def _argv(pid: str) -> list[str]:
    try:
        return (PROC / pid / "cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:
        return []


def node_cpu_seconds(root: int) -> dict[int, tuple[str, float]]:
    """``{pid: (node, CPU seconds)}`` of the node processes descending from process ``root``."""
    parents: dict[int, int] = {}
    cpu: dict[int, float] = {}
    for entry in PROC.iterdir():
        if entry.name.isdigit() and (st := _stat(entry.name)) is not None:
            parents[int(entry.name)], cpu[int(entry.name)] = st
    out = {}
    for pid in cpu:
        p, seen = pid, set()
        while p in parents and p != root and p not in seen:
            seen.add(p)
            p = parents[p]
        if p == root and pid != root and (key := node_key(_argv(str(pid)))) is not None:
            out[pid] = (key, cpu[pid])
    return out


class NodeCpuSampler:
    """Samples :func:`node_cpu_seconds` of this process's descendants until stopped (a context
    manager); :attr:`seconds` is the last reading per node name (summed over its processes)."""

    def __init__(self, period_s: float = 0.05) -> None:
        self.period_s = period_s
        self._last: dict[int, tuple[str, float]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        root = os.getpid()
        while not self._stop.is_set():
            self._last.update(node_cpu_seconds(root))
            self._stop.wait(self.period_s)

    def __enter__(self) -> NodeCpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    @property
    def seconds(self) -> dict[str, float]:
        out: dict[str, float] = {}
        for key, s in self._last.values():
            out[key] = out.get(key, 0.0) + s
        return out


def per_step_us(short: dict[str, float], long: dict[str, float], short_steps: int, long_steps: int) -> dict[str, float]:
    """Each node's CPU µs per step from a short and a long run of the same graph: the difference
    of their CPU seconds over the difference of their steps (start-up cancels out)."""
    extra = long_steps - short_steps
    if extra <= 0:
        raise ValueError(f"the long run needs more steps than the short one ({long_steps} <= {short_steps})")
    return {k: (long[k] - short.get(k, 0.0)) / extra * 1e6 for k in long}


def graph_run(steps: int, driver: str, nodes: str = "by_policy") -> dict:
    """One graph run of ``steps`` steps with BV nodes ``nodes`` (``bvs.nodes``): the simulation
    node's lockstep rate and its flow control's waits (``flow_control_wait_s``)."""
    from evoscen_bringup.graph_runner import GraphOptions, run_graph
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": steps, "bvs.driver": driver, "bvs.nodes": nodes})
    with tempfile.TemporaryDirectory() as tmp:
        stats = Path(tmp) / "stats.json"
        result = run_graph(cfg, Path(tmp), Path(tmp) / "bag",
                           GraphOptions(node_args={"evoscen_sim": {"stats_file": str(stats)}}))
        if result.status != 0 or not stats.exists():
            raise RuntimeError(f"graph run failed: {result.node_status}")
        out = json.loads(stats.read_text())
        out["wall_with_startup_s"] = result.wall_time_s
        return out


def partition_figures(steps: int, repeats: int, driver: str, partitions: list[str]) -> dict:
    """``repeats`` rounds of one graph run per BV-node partition (``bvs.nodes``), interleaved so
    that each round's runs see about the same load; the median rate of each and their ratio to the
    first (docs/architecture.md §5, "BV nodes")."""
    rates: dict[str, list[float]] = {p: [] for p in partitions}
    for _ in range(repeats):
        for p in partitions:
            rates[p].append(graph_run(steps, driver, p)["steps_per_s"])
    med = {p: statistics.median(r) for p, r in rates.items()}
    return {"rates": rates, "median_steps_per_s": med,
            "ratio_to_first": {p: med[p] / med[partitions[0]] for p in partitions}}


def node_cpu_figures(steps: int, driver: str, partitions: list[str]) -> dict:
    """Each node's CPU µs per lockstep step in each partition (:func:`per_step_us`: a run of
    ``steps // 5`` steps and one of ``steps``), the sum over the nodes, and ``2e6 / sum``: the steps/s
    of a 2-core machine that did nothing else and whose cores never waited (an upper bound)."""
    short = max(steps // 5, 100)
    out = {}
    for p in partitions:
        seconds = []
        for n in (short, steps):
            with NodeCpuSampler() as sampler:
                graph_run(n, driver, p)
            seconds.append(sampler.seconds)
        us = per_step_us(seconds[0], seconds[1], short, steps)
        total = sum(us.values())
        out[p] = {"us_per_step": us, "total_us_per_step": total, "two_core_bound_steps_per_s": 2e6 / total}
    return out


def graph_figures(steps: int, repeats: int, driver: str, inprocess_rate: Callable[[int], float]) -> dict:
    """``repeats`` graph runs, each followed at once by an in-process run (recording off), whose
    steps/s ``inprocess_rate(steps)`` measures.

    A shared machine's load changes from minute to minute; the in-process rate timed right
    after each graph run shows what the machine gave at that moment, and the ratio of the two
    is a second figure to compare runs by (it moves less than either, though the latency-bound
    graph suffers more from a busy machine than the in-process runner does). The in-process run
    has ``INPROCESS_PER_GRAPH_STEP`` times the steps, so that it lasts about as long as the graph
    run and sees the same load.
    """
    runs = []
    for _ in range(repeats):
        g = graph_run(steps, driver)
        g["inprocess_steps_per_s"] = inprocess_rate(steps * INPROCESS_PER_GRAPH_STEP)
        g["ratio"] = g["steps_per_s"] / g["inprocess_steps_per_s"]
        runs.append(g)
    rates = [r["steps_per_s"] for r in runs]
    return {"runs": runs, "best_steps_per_s": max(rates), "median_steps_per_s": statistics.median(rates),
            "median_ratio": statistics.median(r["ratio"] for r in runs)}


def report(args, out: dict, partitions: list[str], inprocess_rate: Callable[[int], float],
           recorded: Callable[[], dict]) -> None:
    """Measure and print the graph's figures of ``scripts/bench.py --mode graph`` into ``out["graph"]``:
    ``out`` holds the in-process figures measured before; ``inprocess_rate(steps)`` is the steps/s of one
    in-process run (recording off), ``recorded()`` the figures of a recorded one."""
    drv, steps = args.bv_driver, args.graph_steps
    g = out["graph"] = graph_figures(steps, args.graph_repeats, drv, inprocess_rate)
    runs = g["runs"]
    print(f"evoscen node graph (sim, BV, SUT, evaluator processes; {drv} BVs; lockstep; recording), "
          f"{steps} steps x {len(runs)}, each followed by an in-process run (recording off, "
          f"{steps * INPROCESS_PER_GRAPH_STEP} steps, about as long):")
    for i, r in enumerate(runs, 1):
        print(f"  run {i}: {r['steps_per_s']:8.0f} steps/s lockstep ({r['wall_with_startup_s']:.1f} s with start-up)"
              f"   in-process {r['inprocess_steps_per_s']:8.0f} steps/s   graph / in-process {r['ratio']:.3f}")
    print(f"  best {g['best_steps_per_s']:8.0f} steps/s   median {g['median_steps_per_s']:8.0f} steps/s lockstep   "
          f"(target >= 1000)   median graph / in-process {g['median_ratio']:.3f}")
    rec = recorded()
    print(f"  same scenario in-process: {rec['steps_per_s']:8.0f} steps/s recording on, "
          f"{out['inprocess_median_steps_per_s']:8.0f} steps/s recording off")
    if not partitions:
        return
    pf = g["partitions"] = partition_figures(steps, args.graph_repeats, drv, partitions)
    print(f"BV nodes (bvs.nodes; {drv} BVs), {steps} steps x {args.graph_repeats}, interleaved:")
    for p in partitions:
        runs_text = " ".join(f"{r:.0f}" for r in pf["rates"][p])
        print(f"  {p:10s} median {pf['median_steps_per_s'][p]:8.0f} steps/s lockstep   "
              f"{pf['ratio_to_first'][p] * 100:5.1f} % of {partitions[0]}   (runs: {runs_text})")
    if not args.node_cpu:
        return
    nc = g["node_cpu"] = node_cpu_figures(steps, drv, partitions)
    print(f"CPU per lockstep step by node (difference of a {max(steps // 5, 100)}- and a "
          f"{steps}-step run; user + system, all threads):")
    for p in partitions:
        nodes = "  ".join(f"{k} {v:.0f}" for k, v in sorted(nc[p]["us_per_step"].items()))
        print(f"  {p:10s} {nc[p]['total_us_per_step']:6.0f} us in all ({nodes}); two cores doing nothing "
              f"else: <= {nc[p]['two_core_bound_steps_per_s']:.0f} steps/s")
