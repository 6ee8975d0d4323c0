#!/usr/bin/env python3
"""Run ONE node of the evoscen graph in this process (for containers: one node per container).

    python scripts/graph_node.py NODE [--config FILE] [--steps N] [--seed S] [--sut NAME]
                                 [--bvs N] [--mix C:M:K] [--out DIR] [--overwrite] [--no-plots]
                                 [--external-sut] [--deadline S] [--max-misses N]
                                 [--startup-timeout S]

NODE is ``sim``, ``bv``, ``sut`` or ``eval``; ``bv`` with ``--bv-node NAME`` is the BV node NAME of
``bvs.nodes`` (``--bv-nodes``), without it every BV node of the scenario, each a process of this one
(one BV container for all, as before BV nodes). Every container of a graph must get the same
scenario options: each writes the same parameter files that ``run_scenario.py --mode graph``
writes (``evoscen_bringup.graph_runner.write_parameter_files``) and then becomes its node
(``python -m <package>.<node> --ros-args --params-file ...``), so the bag is the one the
one-machine graph writes. ``ROS_DOMAIN_ID`` comes from the environment (required);
``ROS_AUTOMATIC_DISCOVERY_RANGE`` too (default LOCALHOST); ``EVOSCEN_GRAPH_ARGS`` (shell words) is
appended to the arguments, so one variable gives every container the same scenario options. The evaluator writes the bag to
``DIR/bag`` and the report to ``DIR/report``. Exit status: the node's (docs/docker.md).
Bad input prints one line ``error: ...`` and exits 2.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import tempfile
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT
from run_scenario import add_scenario_options, prepare_output, scenario_overrides  # the same options and checks

NODE_NAMES = {"sim": "evoscen_sim", "bv": "evoscen_bv", "sut": "evoscen_sut", "eval": "evoscen_eval"}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="graph_node.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("node", choices=sorted(NODE_NAMES), help="the node this process becomes")
    ap.add_argument("--bv-node", default=None, metavar="NAME",
                    help="bv: which BV node of bvs.nodes (evoscen_bv_mutual, ...); default: every BV node of "
                         "the scenario, each a process of this one (docs/architecture.md §5, \"BV nodes\")")
    add_scenario_options(ap)
    ap.add_argument("--out", type=Path, default=Path("/data/run"), help="output directory of the evaluator")
    ap.add_argument("--overwrite", action="store_true", help="eval: replace an existing bag and report in DIR")
    ap.add_argument("--no-plots", action="store_true", help="eval: report.json and report.md only")
    ap.add_argument("--external-sut", action="store_true", help="a user's node answers on /evoscen/commands/sut")
    ap.add_argument("--deadline", type=float, default=2.0, help="per-step controller deadline (s)")
    ap.add_argument("--max-misses", type=int, default=5, help="consecutive missed deadlines that abort")
    ap.add_argument("--startup-timeout", type=float, default=60.0, help="how long the nodes wait for each other (s)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:  # the graph's scenario options, shared by every container (docker/compose.yaml)
        argv += shlex.split(os.environ.get("EVOSCEN_GRAPH_ARGS", ""))
    except ValueError as exc:
        print(f"error: EVOSCEN_GRAPH_ARGS: {exc} (expected shell words, e.g. '--steps 3000 --seed 0')",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    args = parse_args(argv)
    from evoscen_bringup.graph_runner import NODES, GraphOptions, node_environment, write_parameter_files
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    name = NODE_NAMES[args.node]
    domain = os.environ.get("ROS_DOMAIN_ID", "")
    if not domain.isdigit() or not 0 <= int(domain) <= 232:
        print(f"error: ROS_DOMAIN_ID = {domain!r}: expected an integer in [0, 232] in the environment "
              "(every node of the graph needs the same one)", file=sys.stderr)
        return EXIT_BAD_INPUT
    discovery = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    for flag, value, ok, allowed in (("--deadline", args.deadline, args.deadline > 0, "a number > 0 (s)"),
                                     ("--max-misses", args.max_misses, args.max_misses >= 1, "an integer >= 1"),
                                     ("--startup-timeout", args.startup_timeout, args.startup_timeout > 0,
                                      "a number > 0 (s)")):
        if not ok:
            print(f"error: {flag} = {value}: expected {allowed}", file=sys.stderr)
            return EXIT_BAD_INPUT
    overrides = scenario_overrides(args)
    try:
        cfg = load_scenario_config(args.config, overrides)
        out = args.out
        bag_dir, report_dir = out / "bag", out / "report"
        if name == "evoscen_eval":
            prepare_output(out, bag_dir, report_dir, overwrite=args.overwrite)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    opts = GraphOptions(domain_id=int(domain), discovery_range=discovery, deadline_s=args.deadline,
                        max_misses=args.max_misses, startup_timeout_s=args.startup_timeout,
                        external_sut=args.external_sut, report_dir=report_dir, report_plots=not args.no_plots)
    params = write_parameter_files(cfg, Path(tempfile.mkdtemp(prefix="evoscen-params-")), bag_dir, opts)
    module = dict(NODES)[name]
    env = node_environment(int(domain), discovery)
    if args.node == "bv":  # the BV nodes of bvs.nodes: the one named, else every one (a process each)
        from evoscen_sim.nodes.bv_nodes import bv_node_names

        names = bv_node_names(cfg)
        if args.bv_node is not None and args.bv_node not in names:
            print(f"error: --bv-node = {args.bv_node!r}: expected one of this scenario's BV nodes (bvs.nodes = "
                  f"{cfg.bvs.nodes}): {', '.join(names) or 'none (bvs.count is 0)'}", file=sys.stderr)
            return EXIT_BAD_INPUT
        names = [args.bv_node] if args.bv_node is not None else names
        argvs = {n: [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[n]), "-r", f"__node:={n}"]
                 for n in names}
        print(f"graph_node: {', '.join(names)} (ROS_DOMAIN_ID={domain}, discovery {discovery})", file=sys.stderr,
              flush=True)
        if len(argvs) == 1:
            os.execve(sys.executable, next(iter(argvs.values())), env)
        return _run_all(argvs, env)
    print(f"graph_node: {name} (ROS_DOMAIN_ID={domain}, discovery {discovery})", file=sys.stderr, flush=True)
    os.execve(sys.executable, [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[name])], env)
    return 0  # not reached


def _run_all(argvs: dict[str, list[str]], env: dict[str, str]) -> int:
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


if __name__ == "__main__":
    sys.exit(main())
