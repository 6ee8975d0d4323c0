#!/usr/bin/env python3
"""Fault-and-fuzz campaign: kills, stalls and hostile messages in node graphs; fuzzed inputs.

    python scripts/fault_campaign.py [--graph-runs N] [--fuzz N] [--steps S] [--seed SEED]
                                     [--classes C,C,...] [--max-stall S] [--out DIR] [--json FILE]

Graph runs (``run_scenario.py --mode graph``, deadline 0.5 s, 3 misses), one fault each, the fault
classes taken in turn and their timing drawn from a generator seeded by ``--seed``: SIGKILL or
SIGTERM to each node during start-up or the lockstep, the evaluator stalled for 2-30 s
(``--max-stall``), a hostile node on the run's domain; faults of the host (root: a disk that fills
up, an output made read-only or removed, the campaign driver killed). Then fuzzed inputs: the
shipped scenario YAML, OpenDRIVE map, a bag, HighD recordings and CLI values, mutated by the same
generator. Each run is checked for its exit status, its end within 10 s of the fault, hangs,
tracebacks, orphans, a bag that opens and steps lost; each fuzzed input must end in success or a
one-line error. What each class does and what is allowed: :mod:`evoscen_experiments.faults`
(docs/recording.md, "Fault campaign").

Prints one line per run and the summary table; exit 0 when every acceptance figure holds, 1 if
not, 2 on bad arguments. Full size (issue 16): ``--graph-runs 100 --fuzz 300``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen import cli

REPO = Path(__file__).resolve().parents[1]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    from evoscen_experiments.faults import fault_classes

    every = len(fault_classes())
    ap = cli.parser("fault_campaign.py", __doc__)
    ap.add_argument("--graph-runs", type=int, default=every, help=f"runs with a fault (default {every}: each class once)")
    ap.add_argument("--fuzz", type=int, default=50, help="fuzzed inputs (default 50)")
    ap.add_argument("--steps", type=int, default=3000, help="steps of each graph run (default 3000)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the campaign's generator (default 0)")
    ap.add_argument("--classes", default=None,
                    help="only these fault classes, comma-separated (e.g. kill:SIGKILL:eval:lockstep,stall,inject; "
                         "default: all, in turn)")
    ap.add_argument("--max-stall", type=float, default=30.0, help="longest evaluator stall in s (default 30)")
    ap.add_argument("--out", type=Path, default=None, help="working directory (default: a temporary one, removed)")
    ap.add_argument("--json", type=Path, default=None, help="also write every result as JSON here")
    return ap.parse_args(argv)


def fuzzed_clis() -> dict:
    """The scripts' ``main(argv)`` the fuzzing calls with hostile values (evoscen_experiments.input_fuzz.CLIS)."""
    import evaluate
    import export_highd
    import replay
    import run_scenario

    return {"run_scenario": run_scenario.main, "evaluate": evaluate.main, "replay": replay.main,
            "export_highd": export_highd.main}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.faults import run_campaign

    return cli.run(lambda: run_campaign(graph_runs=args.graph_runs, fuzz_inputs=args.fuzz, steps=args.steps,
                                        seed=args.seed, classes=args.classes, max_stall_s=args.max_stall,
                                        out=args.out, json_path=args.json, repo=REPO, clis=fuzzed_clis))


if __name__ == "__main__":
    sys.exit(main())
