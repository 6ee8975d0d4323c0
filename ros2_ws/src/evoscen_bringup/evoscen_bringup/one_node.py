"""One node of the graph in this process, for containers (``scripts/graph_node.py``, docs/docker.md).

:func:`become_node` writes the parameter files that ``run_scenario.py --mode graph`` writes
(:func:`~evoscen_bringup.graph_runner.write_parameter_files`) and then becomes the node
(``python -m <package>.<node> --ros-args --params-file ...``), so the bag is the one the one-machine
graph writes; ``bv`` without a node name runs every BV node of ``bvs.nodes`` as a process of this one
(:func:`run_all`). The node's domain and discovery range come from the environment, and
``EVOSCEN_GRAPH_ARGS`` gives every container the same scenario options (:func:`arguments_with_environment`).
"""

from __future__ import annotations

import os
import shlex
import sys
import tempfile
from collections.abc import Mapping
from pathlib import Path

from evoscen_sim.errors import InputError

NODE_NAMES = {"sim": "evoscen_sim", "bv": "evoscen_bv", "sut": "evoscen_sut", "eval": "evoscen_eval"}
"""The nodes a container may become, by the short name ``graph_node.py`` takes."""


def arguments_with_environment(argv: list[str], environ: Mapping[str, str] = os.environ) -> list[str]:
    """``argv`` with the shell words of ``EVOSCEN_GRAPH_ARGS`` appended (the graph's scenario options,
    shared by every container: docker/compose.yaml)."""
    try:
        return list(argv) + shlex.split(environ.get("EVOSCEN_GRAPH_ARGS", ""))
    except ValueError as exc:
        raise InputError(f"EVOSCEN_GRAPH_ARGS: {exc} (expected shell words, e.g. '--steps 3000 --seed 0')") from None


def _checked(deadline: float, max_misses: int, startup_timeout: float, environ: Mapping[str, str]) -> tuple[int, str]:
    """The domain and discovery range of the environment, and the timing options, checked."""
    domain = environ.get("ROS_DOMAIN_ID", "")
    if not domain.isdigit() or not 0 <= int(domain) <= 232:
        raise InputError(f"ROS_DOMAIN_ID = {domain!r}: expected an integer in [0, 232] in the environment "
                         "(every node of the graph needs the same one)")
    for flag, value, ok, allowed in (("--deadline", deadline, deadline > 0, "a number > 0 (s)"),
                                     ("--max-misses", max_misses, max_misses >= 1, "an integer >= 1"),
                                     ("--startup-timeout", startup_timeout, startup_timeout > 0, "a number > 0 (s)")):
        if not ok:
            raise InputError(f"{flag} = {value}: expected {allowed}")
    return int(domain), environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def become_node(node: str, *, config: Path | None, overrides: Mapping[str, str], out: Path, bv_node: str | None = None,
                overwrite: bool = False, plots: bool = True, external_sut: bool = False, deadline: float = 2.0,
                max_misses: int = 5, startup_timeout: float = 60.0) -> int:
    """Become the node ``node`` (a key of :data:`NODE_NAMES`) of the scenario ``config`` with ``overrides``;
    the evaluator writes to ``out/bag`` and ``out/report``. Does not return but for several BV nodes
    (their status, :func:`run_all`); bad input is an InputError before anything is started."""
    from evoscen_bringup.graph_runner import NODES, GraphOptions, node_environment, write_parameter_files
    from evoscen_bringup.output import prepare_output
    from evoscen_sim.config.scenario_config import load_scenario_config

    name = NODE_NAMES[node]
    domain, discovery = _checked(deadline, max_misses, startup_timeout, os.environ)
    cfg = load_scenario_config(config, dict(overrides))
    bag_dir, report_dir = out / "bag", out / "report"
    if name == "evoscen_eval":
        prepare_output(out, bag_dir, report_dir, overwrite=overwrite)
    opts = GraphOptions(domain_id=domain, discovery_range=discovery, deadline_s=deadline, max_misses=max_misses,
                        startup_timeout_s=startup_timeout, external_sut=external_sut, report_dir=report_dir,
                        report_plots=plots)
    params = write_parameter_files(cfg, Path(tempfile.mkdtemp(prefix="evoscen-params-")), bag_dir, opts)
    module = dict(NODES)[name]
    env = node_environment(domain, discovery)
    if node == "bv":  # the BV nodes of bvs.nodes: the one named, else every one (a process each)
        from evoscen_sim.nodes.bv_nodes import bv_node_names

        names = bv_node_names(cfg)
        if bv_node is not None and bv_node not in names:
            raise InputError(f"--bv-node = {bv_node!r}: expected one of this scenario's BV nodes (bvs.nodes = "
                             f"{cfg.bvs.nodes}): {', '.join(names) or 'none (bvs.count is 0)'}")
        names = [bv_node] if bv_node is not None else names
        argvs = {n: [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[n]), "-r", f"__node:={n}"]
                 for n in names}
        print(f"graph_node: {', '.join(names)} (ROS_DOMAIN_ID={domain}, discovery {discovery})", file=sys.stderr,
              flush=True)
        if len(argvs) == 1:
            os.execve(sys.executable, next(iter(argvs.values())), env)
        return run_all(argvs, env)
    print(f"graph_node: {name} (ROS_DOMAIN_ID={domain}, discovery {discovery})", file=sys.stderr, flush=True)
    os.execve(sys.executable, [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[name])], env)
    return 0  # not reached


def run_all(argvs: dict[str, list[str]], env: dict[str, str]) -> int:
    """Run several BV nodes as children until all have ended; SIGINT/SIGTERM are passed on to them.
    The exit status is the first non-zero one of the nodes (a signal as 128 + its number), else 0."""
    import signal
    import subprocess

    procs = {n: subprocess.Popen(argv, env=env) for n, argv in argvs.items()}

    def forward(signum, frame):
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signum)

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, forward)
    codes = [p.wait() for p in procs.values()]
    bad = [c for c in codes if c != 0]
    if not bad:
        return 0
    return bad[0] if bad[0] > 0 else 128 - bad[0]
