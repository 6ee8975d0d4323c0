"""A campaign from its spec to its summary (docs/campaigns.md): what ``scripts/campaign.py`` does.

:func:`main` loads and expands the spec (:mod:`evoscen_experiments.campaign_spec`), ends the Ray processes an
earlier killed driver of the same output left (:mod:`evoscen_experiments.ray_leftovers`), runs what is not
done yet behind a progress bar (:func:`evoscen_experiments.campaign.run_campaign`), writes the results and
the summary (:mod:`evoscen_experiments.campaign_summary`) and gives the exit status of the ending: done, a
run failed, a fault of the host, interrupted.
"""

from __future__ import annotations

import sys
from pathlib import Path

from evoscen_contract.contract import EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_OK
from evoscen_sim.errors import HostFault, InputError

FIX = "free space on the disk (or make the output directory writable), then run the same command again to continue"
"""What to do after a fault of the host: the finished runs are kept, the same command continues."""


def _spec_and_runs(args):
    """The workers, retries, spec, runs and output directory of the parsed options (InputError of one line)."""
    from evoscen_experiments.campaign_spec import expand, load_spec
    from evoscen_experiments.experiments import positive_int

    cpus = positive_int("--cpus", args.cpus)
    retries = positive_int("--retries", args.retries, 0)
    spec = load_spec(args.spec)
    runs = expand(spec)
    out = args.out if args.out is not None else Path("runs/campaigns") / spec.name
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a directory")
    return cpus, retries, spec, runs, out


def main(args) -> int:
    """The campaign of the parsed options (``scripts/campaign.py``; text values, checked here): runs what is not
    done, writes ``results.parquet`` and ``summary.md``. Returns the exit status (0 done, 3 some runs failed,
    5 a fault of the host, 130 interrupted); InputError (one line) on bad input, before anything runs."""
    from tqdm import tqdm

    from evoscen_experiments.campaign import run_campaign
    from evoscen_experiments.campaign_summary import write_results
    from evoscen_experiments.ray_leftovers import end_leftovers

    cpus, retries, spec, runs, out = _spec_and_runs(args)
    left = end_leftovers(out)
    if left:
        print(f"campaign: ended {len(left)} Ray process(es) left running by an earlier driver of {out} that was killed: "
              + ", ".join(f"{name} (pid {pid})" for pid, name in left), file=sys.stderr)
    done_before = sum((out / "runs" / r.key / "result.json").exists() for r in runs)
    print(f"campaign {spec.name}: {len(runs)} runs ({len(runs) // len(spec.seeds)} cells x {len(spec.seeds)} seeds), "
          f"{done_before} already done; results in {out}", file=sys.stderr)
    bar = tqdm(total=len(runs), initial=done_before, unit="run", desc=spec.name, file=sys.stderr)

    def progress(done: int, total: int, rate: float, steps_per_s: float) -> None:  # over the command's wall
        bar.n = done
        bar.set_postfix_str(f"{rate:.2f} runs/s, {steps_per_s:,.0f} SUT-steps/s")
        bar.refresh()

    try:
        result = run_campaign(runs, out, record=spec.record, clip_s=spec.clip_s, address=args.address, cpus=cpus,
                              retries=retries, progress=progress)
    except KeyboardInterrupt:  # before Ray was up
        bar.close()
        print("interrupted: run the same command again to continue", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        bar.close()
    if result.host_fault is not None:  # one line; the finished runs are kept, that run is not marked done
        print(f"error: campaign stopped: {result.host_fault}; {FIX} ({result.already_done + result.computed} "
              f"of {len(runs)} runs done are kept)", file=sys.stderr)
        return EXIT_HOST_FAULT
    try:
        write_results(spec, runs, out)
    except HostFault as exc:
        print(f"error: campaign: {exc}; {FIX} (every finished run is kept)", file=sys.stderr)
        return EXIT_HOST_FAULT
    print(f"{result.computed} runs computed in {result.wall_s:.1f} s on {len(result.nodes) or 0} node(s), "
          f"{result.already_done} already done; {out / 'results.parquet'}, {out / 'summary.md'}")
    from evoscen_experiments.timing import finish

    finish(out)  # the command's start-up and throughput (docs/performance.md "Start-up")
    for line in result.failed:
        print(f"error: run failed: {line}", file=sys.stderr)
    if result.interrupted:
        print("interrupted: finished runs are kept; run the same command again to continue", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_FAULT if result.failed else EXIT_OK
