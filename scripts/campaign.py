#!/usr/bin/env python3
"""Run a campaign: every run of a YAML spec on Ray, each once (docs/campaigns.md).

    python scripts/campaign.py SPEC [--out DIR] [--address ADDR] [--cpus N] [--retries N]

The spec (see ``examples/campaigns/``) gives the scenario, the seeds, fixed overrides and a
grid of axes (scenario keys, ``mutant``); every cell runs on every seed as one Ray task of one
CPU. Results go to ``--out`` (default ``runs/campaigns/<name>``): ``runs/<key>/result.json``
and ``report.json`` per run, ``results.parquet`` (one row per run) and ``summary.md`` (per-cell
means with 95 % intervals; paired differences with ``compare``). A run whose result exists is
never recomputed: run the same command again after Ctrl-C to continue. ``--address`` joins a
running Ray cluster (``ray start --head``); by default Ray starts here with ``--cpus`` workers
(default: every CPU). Exit status: 0 done, 2 bad input, 3 some runs failed, 5 a fault of the host
(a full disk, an unwritable output: one line; the run it hit is not marked done, the same command
continues once it is gone), 130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_OK


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="campaign.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("spec", type=Path, help="campaign spec (YAML)")
    ap.add_argument("--out", type=Path, help="output directory (default runs/campaigns/<spec name>)")
    ap.add_argument("--address", help="join this Ray cluster (e.g. 10.0.0.5:6379 or 'auto') instead of starting one")
    ap.add_argument("--cpus", default=str(os.cpu_count() or 1), help="workers of the local Ray (default: CPU count)")
    ap.add_argument("--retries", default="3", help="retries of a run whose worker dies (default 3)")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from evoscen_experiments.campaign import run_campaign
    from evoscen_experiments.campaign_spec import expand, load_spec
    from evoscen_experiments.campaign_summary import write_results
    from evoscen_experiments.experiments import positive_int
    from evoscen_sim.errors import HostFault, InputError

    try:
        cpus = positive_int("--cpus", args.cpus)
        retries = positive_int("--retries", args.retries, 0)
        spec = load_spec(args.spec)
        runs = expand(spec)
        out = args.out if args.out is not None else Path("runs/campaigns") / spec.name
        if out.exists() and not out.is_dir():
            raise InputError(f"--out {out}: exists and is not a directory")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from evoscen_experiments.ray_leftovers import end_leftovers
    from tqdm import tqdm

    left = end_leftovers(out)
    if left:
        print(f"campaign: ended {len(left)} Ray process(es) left running by an earlier driver of {out} that was killed: "
              + ", ".join(f"{name} (pid {pid})" for pid, name in left), file=sys.stderr)
    done_before = sum((out / "runs" / r.key / "result.json").exists() for r in runs)
    print(f"campaign {spec.name}: {len(runs)} runs ({len(runs) // len(spec.seeds)} cells x {len(spec.seeds)} seeds), "
          f"{done_before} already done; results in {out}", file=sys.stderr)
    bar = tqdm(total=len(runs), initial=done_before, unit="run", desc=spec.name, file=sys.stderr)

    def progress(done: int, total: int, rate: float) -> None:
        bar.n = done
        bar.set_postfix_str(f"{rate:.2f} runs/s")
        bar.refresh()

    try:
        result = run_campaign(runs, out, record=spec.record, clip_s=spec.clip_s, address=args.address, cpus=cpus,
                              retries=retries,
                              progress=progress)
    except KeyboardInterrupt:  # before Ray was up
        bar.close()
        print("interrupted: run the same command again to continue", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        bar.close()
    fix = "free space on the disk (or make the output directory writable), then run the same command again to continue"
    if result.host_fault is not None:  # one line; the finished runs are kept, that run is not marked done
        print(f"error: campaign stopped: {result.host_fault}; {fix} ({result.already_done + result.computed} "
              f"of {len(runs)} runs done are kept)", file=sys.stderr)
        return EXIT_HOST_FAULT
    try:
        write_results(spec, runs, out)
    except HostFault as exc:
        print(f"error: campaign: {exc}; {fix} (every finished run is kept)", file=sys.stderr)
        return EXIT_HOST_FAULT
    print(f"{result.computed} runs computed in {result.wall_s:.1f} s on {len(result.nodes) or 0} node(s), "
          f"{result.already_done} already done; {out / 'results.parquet'}, {out / 'summary.md'}")
    for line in result.failed:
        print(f"error: run failed: {line}", file=sys.stderr)
    if result.interrupted:
        print("interrupted: finished runs are kept; run the same command again to continue", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_FAULT if result.failed else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
