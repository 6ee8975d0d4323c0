#!/usr/bin/env python3
"""Run ONE node of the evoscen graph in this process (for containers: one node per container).

    python scripts/graph_node.py NODE [--config FILE] [--steps N] [--seed S] [--sut NAME]
                                 [--bvs N] [--mix C:M:K] [--out DIR] [--overwrite] [--no-plots]
                                 [--external-sut] [--deadline S] [--max-misses N]
                                 [--startup-timeout S]

NODE is ``sim``, ``bv``, ``sut`` or ``eval``; ``bv`` with ``--bv-node NAME`` is the BV node NAME of
``bvs.nodes`` (``--bv-nodes``), without it every BV node of the scenario, each a process of this one.
Every container of a graph must get the same scenario options: each writes the parameter files
``run_scenario.py --mode graph`` writes and becomes its node, so the bag is the one-machine graph's.
``ROS_DOMAIN_ID`` comes from the environment (required), ``ROS_AUTOMATIC_DISCOVERY_RANGE`` too
(default LOCALHOST); ``EVOSCEN_GRAPH_ARGS`` (shell words) is appended to the arguments. The evaluator
writes the bag to ``DIR/bag`` and the report to ``DIR/report``. Exit status: the node's
(docs/docker.md); bad input prints one line ``error: ...`` and exits 2. The work is
:func:`evoscen_bringup.one_node.become_node`.
"""

from __future__ import annotations

import argparse
import sys

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen_bringup.one_node import NODE_NAMES
from run_scenario import add_scenario_options  # the same scenario options


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = cli.parser("graph_node.py", __doc__)
    ap.add_argument("node", choices=sorted(NODE_NAMES), help="the node this process becomes")
    ap.add_argument("--bv-node", default=None, metavar="NAME",
                    help="bv: which BV node of bvs.nodes (evoscen_bv_mutual, ...); default: every BV node of "
                         "the scenario, each a process of this one (docs/architecture.md §5, \"BV nodes\")")
    add_scenario_options(ap)
    cli.add_out(ap, "/data/run", "output directory of the evaluator")
    ap.add_argument("--overwrite", action="store_true", help="eval: replace an existing bag and report in DIR")
    ap.add_argument("--no-plots", action="store_true", help="eval: report.json and report.md only")
    ap.add_argument("--external-sut", action="store_true", help="a user's node answers on /evoscen/commands/sut")
    ap.add_argument("--deadline", type=float, default=2.0, help="per-step controller deadline (s)")
    ap.add_argument("--max-misses", type=int, default=5, help="consecutive missed deadlines that abort")
    ap.add_argument("--startup-timeout", type=float, default=60.0, help="how long the nodes wait for each other (s)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    from evoscen_bringup.one_node import arguments_with_environment, become_node
    from evoscen_bringup.runs import scenario_overrides

    def work() -> int:
        args = parse_args(arguments_with_environment(sys.argv[1:] if argv is None else argv))
        return become_node(args.node, config=args.config, overrides=scenario_overrides(vars(args)), out=args.out,
                           bv_node=args.bv_node, overwrite=args.overwrite, plots=not args.no_plots,
                           external_sut=args.external_sut, deadline=args.deadline, max_misses=args.max_misses,
                           startup_timeout=args.startup_timeout)

    return cli.run(work)


if __name__ == "__main__":
    sys.exit(main())
