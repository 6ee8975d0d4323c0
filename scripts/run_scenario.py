#!/usr/bin/env python3
"""Run an evoscen scenario, record it as a rosbag2 (MCAP) bag and score it.

    python scripts/run_scenario.py --mode inprocess [--config FILE] [--steps N] [--seed S]
                                   [--sut NAME] [--bvs N] [--mix C:M:K] [--out DIR]

The bag goes to ``DIR/bag/``, the report to ``DIR/report/`` and the resolved configuration to
``DIR/scenario.yaml``; ``--steps``, ``--seed``, ``--sut``, ``--bvs`` and ``--mix`` override the
config's keys (with the same validation). Bad input: one line ``error: ...``, status 2. Ctrl-C:
a finished bag (``run_end`` of kind ``interrupted``), status 130. An output that cannot be written
(a full disk, a read-only or removed directory): one line ``error: cannot write FILE: CAUSE; ...``
saying what became of the bag, status 5 (docs/recording.md). The work is
:func:`evoscen_bringup.runs.run_command`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli
from evoscen_bringup.runs import MODES, SCENARIO_OPTIONS


def add_scenario_options(ap: argparse.ArgumentParser) -> None:
    """The scenario options (``--config`` and the key overrides), shared with graph_node.py."""
    cli.add_config(ap)
    for option, _key, text in SCENARIO_OPTIONS:
        ap.add_argument(option, help=text)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    from evoscen import __version__
    from evoscen_bringup.domains import DISCOVERY_RANGES

    ap = cli.parser("run_scenario.py", __doc__)
    ap.add_argument("--version", action="version", version=f"evoscen {__version__}")
    ap.add_argument("--mode", default="graph", choices=MODES,
                    help="graph (default): one ROS 2 process per node, lockstep; inprocess: all cores in one process, "
                         "no middleware")
    add_scenario_options(ap)
    ap.add_argument("--start-from", type=Path, default=None, metavar="FILE.xosc",
                    help="start from the initial state of an exported OpenSCENARIO file (its vehicles, lanes, "
                    "positions, speeds and sizes) instead of the spawn layout; --mode inprocess (docs/export.md)")
    ap.add_argument("--list-suts", action="store_true",
                    help="list the installed SUT models (name, built-in or entry point package, description) and exit")
    ap.add_argument("--list-mutants", action="store_true",
                    help="list the SUT mutants (name, class, the SUT models they apply to, description) and exit")
    ap.add_argument("--out", default="runs/latest", help="output directory (default runs/latest)")
    ap.add_argument("--no-record", action="store_true", help="do not record a bag")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing bag in OUT/bag and report in OUT/report")
    ap.add_argument("--no-plots", action="store_true", help="report.json and report.md only, no PNG plots")
    ap.add_argument("--quiet", action="store_true", help="no progress bar (inprocess)")
    ap.add_argument("--bag-writer", default="auto", choices=("auto", "inline", "process"),
                    help="inprocess: write the bag between the steps (inline) or in a forked writer process "
                         "(process), the same bytes; auto (default): process when more than one CPU is usable "
                         "(docs/recording.md)")
    g = ap.add_argument_group("graph mode")
    g.add_argument("--domain-id", help="ROS_DOMAIN_ID of the nodes (default: a free one of 1..100, drawn at random; "
                   "no two evoscen graphs on one host share a domain)")
    g.add_argument("--discovery-range", default="LOCALHOST", choices=DISCOVERY_RANGES,
                   help="ROS_AUTOMATIC_DISCOVERY_RANGE: SUBNET lets ROS 2 machines on the network see the topics")
    g.add_argument("--deadline", type=float, default=2.0, help="per-step controller deadline in seconds (default 2.0)")
    g.add_argument("--max-misses", default="5", help="consecutive missed deadlines that abort (default 5)")
    g.add_argument("--wait-for", nargs="+", default=[], metavar="NODE",
                   help="node names of your own nodes (a monitor, a bridge) to wait for before step 0, "
                        "so they receive every step; a BV node of the scenario named here (evoscen_bv_mutual) "
                        "is not started: start it by hand with OUT/params/<name>.yaml (docs/architecture.md §5)")
    g.add_argument("--external-sut", action="store_true",
                   help="do not start evoscen's SUT node: your own node answers on /evoscen/commands/sut "
                        "(see examples/README.md)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.list_suts or args.list_mutants:
        from evoscen_bringup.model_lists import list_mutants, list_suts

        return cli.run(lambda: print("\n".join(list_suts() if args.list_suts else list_mutants())))
    from evoscen_bringup.runs import run_command, scenario_overrides

    return cli.run(lambda: run_command(
        mode=args.mode, config=args.config, overrides=scenario_overrides(vars(args)), out=args.out,
        start_from=args.start_from, record=not args.no_record, overwrite=args.overwrite, plots=not args.no_plots,
        quiet=args.quiet, bag_writer=args.bag_writer, domain_id=args.domain_id, discovery_range=args.discovery_range,
        deadline=args.deadline, max_misses=args.max_misses, wait_for=tuple(args.wait_for),
        external_sut=args.external_sut))


if __name__ == "__main__":
    sys.exit(main())
