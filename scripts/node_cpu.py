"""CPU time of each node of a graph run, per lockstep step (``scripts/bench.py --node-cpu``).

A graph run's nodes are child processes of the launcher; :class:`NodeCpuSampler` reads their
CPU time (user + system, all threads) from ``/proc`` every ``period_s`` while the run goes, and
keeps the last reading of each, since a node's process is gone once the run ends. A node is
named by its ROS node name (``-r __node:=NAME``) or else by the package of its ``-m`` module
(``evoscen_sim``, ``evoscen_sut``, ``evoscen_eval``, ``evoscen_bv``).

A run's CPU time includes each node's start-up (imports, compiled kernels loaded, discovery),
seconds on a 2-core machine; :func:`per_step_us` takes the difference of two runs of different
lengths, which leaves the cost of the steps alone (docs/performance.md, "BV nodes").
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

PROC = Path("/proc")


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
