#!/usr/bin/env python3
"""Benchmark: in-process simulation speed, recorded-bag size, and SUMO for reference.

    python scripts/bench.py [--mode inprocess|graph] [--steps 5000] [--repeats 5] [--bag-steps 10000] [--no-sumo]
                            [--bv-driver level0|learned] [--bv-nodes single,by_policy] [--node-cpu]
                            [--sut-models] [--learned] [--experiment] [--makeups highd,uniform] [--batched 1,8,64] [--json]

For the shipped default scenario (1 SUT + 20 BVs, dt 0.1 s) with the BV drivers of ``--bv-driver``
(default ``level0``, the rule-based drivers SUMO is compared with): in-process steps/s with recording
off (best and median of ``--repeats`` timed runs of ``--steps`` steps after a warm-up); a
``--bag-steps`` recorded run (steps/s and the bag's size); one world under each traffic make-up of
``--makeups`` (``bvs.makeup``: level-0 BVs, with ``--learned`` learned BVs too; one BV driver) beside
SUMO, timed repeats alternated, in steps/s and vehicle-steps/s with their ratios; with the optional ``libsumo``
(requirements-bench.txt) SUMO's rate on the same road and traffic volume in this same process and the
ratio evoscen / SUMO. ``--mode graph`` adds the node graph's lockstep rate beside in-process runs, the
BV-node partitions of ``--bv-nodes`` and, with ``--node-cpu``, each node's CPU time per step;
``--learned`` the learned BVs' cost; ``--experiment`` a small sensitivity experiment's throughput on
``--jobs`` Ray workers beside the core's rate; ``--sut-models`` every SUT model's per-decision cost;
``--batched`` many worlds stepped in lockstep in each of ``--jobs`` processes, in vehicle-steps/s beside
libsumo's (:mod:`evoscen_experiments.bench_batched`).

Figures, not assertions (docs/performance.md; the figures are in
:mod:`evoscen_experiments.bench` and :mod:`evoscen_experiments.bench_graph`). Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import os
import sys

import _bootstrap  # noqa: F401
from evoscen import cli


def parse_args(argv: list[str] | None):
    ap = cli.parser("bench.py", __doc__, ranks_by="speed")
    ap.add_argument("--steps", type=int, default=5000, help="timed steps per repeat (default 5000)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats (default 5)")
    ap.add_argument("--bag-steps", type=int, default=10000, help="steps of the recorded run (default 10000; 0 = skip)")
    ap.add_argument("--no-sumo", action="store_true", help="skip the SUMO reference even if libsumo is installed")
    ap.add_argument("--mode", choices=("inprocess", "graph"), default="inprocess",
                    help="graph: also the lockstep rate of the node graph (default: in-process only)")
    ap.add_argument("--graph-steps", type=int, default=5000, help="steps of each graph run (default 5000)")
    ap.add_argument("--graph-repeats", type=int, default=3, help="graph runs (default 3)")
    ap.add_argument("--bv-nodes", default="single,by_policy",
                    help="graph: also compare these BV-node partitions (bvs.nodes), comma-separated, the first "
                         "the reference (default single,by_policy; with --bv-driver learned by_policy is three BV "
                         "nodes, with level0 one; empty: skip)")
    ap.add_argument("--node-cpu", action="store_true",
                    help="graph: also each node's CPU time per step in each --bv-nodes partition")
    ap.add_argument("--sut-models", action="store_true", help="also the per-decision cost of every SUT model")
    ap.add_argument("--learned", action="store_true",
                    help="also the learned BVs' inference cost and the in-process rate with learned vs level-0 BVs")
    ap.add_argument("--experiment", action="store_true",
                    help="also the throughput of a small sensitivity experiment beside the core's rate")
    ap.add_argument("--experiment-episodes", type=int, default=8,
                    help="--experiment: seeds (episodes per variant; default 8)")
    ap.add_argument("--experiment-mutants", default="tailgating,blind_behind,stale",
                    help="--experiment: mutants of MOBIL run beside it (default tailgating,blind_behind,stale)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                    help="--experiment: Ray workers (default: CPU count)")
    ap.add_argument("--bv-driver", choices=("level0", "learned"), default="level0",
                    help="the BVs' drivers in every figure but --learned's (default level0)")
    ap.add_argument("--makeups", default="highd,uniform",
                    help="one world's rate under each of these bvs.makeup, comma-separated (level-0 BVs, with "
                         "--learned also learned BVs; one BV driver), alternated with SUMO's, in steps/s and "
                         "vehicle-steps/s, and their ratios (default highd,uniform; empty: skip)")
    ap.add_argument("--batched", default="",
                    help="also batched worlds: these batch sizes, comma-separated (e.g. 1,8,64), stepped in lockstep "
                         "in each of --jobs processes, in vehicle-steps/s beside libsumo's (default: skip)")
    ap.add_argument("--json", action="store_true", help="also print the figures as one JSON line")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments import bench

    return cli.run(lambda: bench.run(args))


if __name__ == "__main__":
    sys.exit(main())
