#!/usr/bin/env python3
"""CPU time per step of the SUT driver and of the whole scored step, for MOBIL and its mutants.

    python scripts/sut_step_cost.py [--mutants all|NAME,...] [--repeats 2] [--episode-steps 300]

Runs, as the sensitivity experiment runs its episodes (evolving scenario, from a shared start, no bag,
scored, one process, no Ray), MOBIL and each mutant ``--repeats`` times in turn (seeds 96000, 96001,
...), after one untimed round (kernels loaded), and prints per variant the CPU time
(``time.process_time``: less sensitive than wall time to other processes on a shared machine) per
step of the SUT driver's ``act`` and of the scored step loop, and each variant's ``act`` over
MOBIL's: the figures of docs/performance.md "Per-step work of the SUT drivers". Exit status: 0,
2 bad input.
"""

from __future__ import annotations

import argparse
import sys
import time

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

FIRST_SEED = 96000


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="sut_step_cost.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutants of MOBIL")
    ap.add_argument("--repeats", default="2", help="timed episodes per variant (default 2)")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    args = ap.parse_args(argv)
    from evoscen_experiments.experiments import distinct_names, positive_int
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY

    try:
        repeats = positive_int("--repeats", args.repeats)
        steps = positive_int("--episode-steps", args.episode_steps)
        mutants = list(LIBRARY) if args.mutants.strip() == "all" else distinct_names("--mutants", args.mutants)
        unknown = [m for m in mutants if m not in LIBRARY]
        if unknown:
            raise InputError(f"--mutants: unknown mutant {unknown[0]!r}: expected 'all' or names from "
                             f"{', '.join(LIBRARY)}")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for line in measure(mutants, repeats, steps):
        print(line)
    return EXIT_OK


def measure(mutants: list[str], repeats: int, steps: int) -> list[str]:
    """The report's lines (see the module docstring)."""
    import evoscen_sim.loop.step_loop as step_loop
    from evoscen_bringup import inprocess, starts
    from evoscen_experiments.experiments import config_loader
    from evoscen_sut.mutants import mutant_overrides

    loop_s = [0.0]
    inner_run = step_loop.StepLoop.run

    def timed_run(self, *a, **k):
        t = time.process_time()
        try:
            return inner_run(self, *a, **k)
        finally:
            loop_s[0] += time.process_time() - t

    variants = {"mobil": {"sut.model": "mobil"}} | {m: mutant_overrides("mobil", m) for m in mutants}
    load = config_loader(None)
    cache = starts.StartCache()

    def episode(name: str, seed: int) -> tuple[float, float]:
        cfg = load({**variants[name], "seed": str(seed), "steps": str(steps), "recording.enabled": "false"})
        sc = cache.scenario(cfg, partitioned=False)
        act_s = [0.0]
        inner_act = sc.sut.act

        def act(view):
            t = time.process_time()
            try:
                return inner_act(view)
            finally:
                act_s[0] += time.process_time() - t

        sc.sut.act = act
        loop_s[0] = 0.0
        inprocess.run_inprocess(cfg, bag_dir=None, scenario=sc, evaluate=True, plots=False)
        return act_s[0], loop_s[0]

    step_loop.StepLoop.run = timed_run
    try:
        for name in variants:  # kernels loaded, files cached: not timed
            episode(name, FIRST_SEED)
        totals = {name: [0.0, 0.0] for name in variants}
        for r in range(repeats):
            for name in variants:
                a, s = episode(name, FIRST_SEED + r)
                totals[name][0] += a
                totals[name][1] += s
    finally:
        step_loop.StepLoop.run = inner_run
    n = repeats * steps
    base = totals["mobil"][0] / n
    lines = [f"MOBIL + {len(mutants)} mutants, evolving scenario, {repeats} episode(s) x {steps} scored steps each, "
             "CPU us per step:", f"  {'variant':24s} {'SUT act':>8s} {'x MOBIL':>8s} {'scored step':>12s}"]
    for name, (a, s) in totals.items():
        lines.append(f"  {name:24s} {a / n * 1e6:8.1f} {a / n / base:8.2f} {s / n * 1e6:12.1f}")
    return lines


if __name__ == "__main__":
    sys.exit(main())
