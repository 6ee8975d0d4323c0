#!/usr/bin/env python3
"""Where an experiment episode's time goes: set-up, warm-up, stepping, scoring — one process, no Ray.

    python scripts/profile_episodes.py [--scenario evolving|level0|nilsson|mobil] [--seeds 2]
                                       [--mutants all|NAME,...] [--episode-steps 300]

Runs, for each of ``--seeds`` seeds (from 96000), MOBIL and its mutants (``--mutants``, default
all ten) as the sensitivity experiment runs its episodes (no bag, scored), two ways, alternated
seed by seed so that both see the same load of a shared machine:

* **per run**: every episode built from scratch — the scenario file parsed, the warm-up run, the
  BV drivers of every BV node built (how each episode was computed before shared starts);
* **shared start**: the file parsed once, the warm-up and the BV driver built once per seed and
  copied for every variant, one driver of all BVs (:mod:`evoscen_bringup.starts`; what the
  experiments do now).

Prints per episode the wall time of each phase (timers around the functions that do it) and the
speed-up, and checks that both ways give the same reports (byte for byte as JSON): a figure for
docs/performance.md "Experiments". Exit status: 0, 1 when the reports differ, 2 bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK

FIRST_SEED = 96000
START = "start: the seed's first built (warm-up, BV driver), the others copied"
SCENARIOS = ("evolving", "level0", "nilsson", "mobil")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="profile_episodes.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="evolving", help=f"one of {', '.join(SCENARIOS)} (default evolving)")
    ap.add_argument("--seeds", default="2", help="seeds, each run both ways (default 2)")
    ap.add_argument("--mutants", default="all", help="'all' or comma-separated mutants of MOBIL")
    ap.add_argument("--episode-steps", default="300", help="steps per episode (default 300)")
    args = ap.parse_args(argv)
    from evoscen_experiments.experiments import distinct_names, positive_int
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY

    try:
        if args.scenario not in SCENARIOS:
            raise InputError(f"--scenario {args.scenario!r}: expected one of {', '.join(SCENARIOS)}")
        seeds = positive_int("--seeds", args.seeds)
        steps = positive_int("--episode-steps", args.episode_steps)
        mutants = list(LIBRARY) if args.mutants.strip() == "all" else distinct_names("--mutants", args.mutants)
        unknown = [m for m in mutants if m not in LIBRARY]
        if unknown:
            raise InputError(f"--mutants: unknown mutant {unknown[0]!r}: expected 'all' or names from "
                             f"{', '.join(LIBRARY)}")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    same = profile(args.scenario, seeds, mutants, steps)
    return EXIT_OK if same else 1


def profile(scenario: str, seeds: int, mutants: list[str], steps: int) -> bool:
    """Print the phases of both ways (see the module docstring); True when every report is the same."""
    import evoscen_sim.loop.step_loop as step_loop
    from evoscen_bringup import inprocess, starts
    from evoscen_bringup import scenario as scenario_mod
    from evoscen_experiments.experiments import Round, config_loader
    from evoscen_sim import scenario_builders
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sut.mutants import mutant_overrides

    phases: dict[str, float] = {}

    def timed(owner, name: str, label: str) -> None:
        inner = getattr(owner, name)

        def wrapper(*a, **k):
            t = time.perf_counter()
            try:
                return inner(*a, **k)
            finally:
                phases[label] = phases.get(label, 0.0) + time.perf_counter() - t

        setattr(owner, name, wrapper)

    timed(scenario_builders, "warm_up", f"warm-up ({_warmup_text()})")
    timed(scenario_mod, "build_bv_drivers", "BV drivers (one per BV node)")
    timed(starts, "_bv_driver", "BV driver (one, per start)")
    timed(step_loop.StepLoop, "run", f"steps ({steps}, scored: drivers, world, events, scores)")
    timed(inprocess, "_report", "final report")

    variants = [{"sut.model": "mobil"}] + [mutant_overrides("mobil", m) for m in mutants]

    def overrides(seed: int, v: dict) -> dict:
        o = {**v, "seed": str(seed), "steps": str(steps), "recording.enabled": "false"}
        if scenario != "evolving":
            o["bvs.driver"] = scenario
        return o

    load = config_loader(None)
    cache = starts.StartCache()

    def per_run(seed: int) -> list[str]:
        out = []
        for v in variants:
            t = time.perf_counter()
            cfg = load_scenario_config(None, overrides(seed, v))
            _ = Round("x", cfg).key
            phases["configuration and run key"] = phases.get("configuration and run key", 0.0) + time.perf_counter() - t
            s = inprocess.run_inprocess(cfg, bag_dir=None, scenario=scenario_mod.build_scenario(cfg), evaluate=True,
                                        plots=False)
            out.append(json.dumps(s.report, sort_keys=True))
        return out

    def shared(seed: int) -> list[str]:
        out = []
        for v in variants:
            t = time.perf_counter()
            cfg = load(overrides(seed, v))
            _ = Round("x", cfg).key
            phases["configuration and run key"] = phases.get("configuration and run key", 0.0) + time.perf_counter() - t
            t = time.perf_counter()
            sc = cache.scenario(cfg, partitioned=False)
            phases[START] = phases.get(START, 0.0) + time.perf_counter() - t
            s = inprocess.run_inprocess(cfg, bag_dir=None, scenario=sc, evaluate=True, plots=False)
            out.append(json.dumps(s.report, sort_keys=True))
        return out

    per_run(FIRST_SEED - 1)  # compiled kernels loaded, files cached: not timed
    shared(FIRST_SEED - 1)
    totals: dict[str, dict[str, float]] = {"per run": {}, "shared start": {}}
    same = True
    for k in range(seeds):
        seed = FIRST_SEED + k
        order = (("per run", per_run), ("shared start", shared))
        reports = {}
        for name, fn in order if k % 2 == 0 else order[::-1]:
            phases.clear()
            t = time.perf_counter()
            reports[name] = fn(seed)
            phases["total"] = time.perf_counter() - t
            for label, s in phases.items():
                totals[name][label] = totals[name].get(label, 0.0) + s
        same = same and reports["per run"] == reports["shared start"]
    n = seeds * len(variants)
    print(f"{scenario} scenario, MOBIL + {len(mutants)} mutants, {seeds} seed(s) x {len(variants)} variants = {n} "
          f"episodes each way, {steps} steps after the warm-up; ms per episode (alternated seed by seed):")
    for name, t in totals.items():
        print(f"  {name}: {t['total'] / n * 1e3:8.1f} ms")
        for label, s in sorted(t.items(), key=lambda x: -x[1]):
            if label != "total":
                print(f"    {label:70s} {s / n * 1e3:8.1f}")
    speed_up = totals["per run"]["total"] / totals["shared start"]["total"]
    print(f"  speed-up {speed_up:.2f}x; reports {'the same' if same else 'DIFFER'} (JSON, byte for byte)")
    return same


def _warmup_text() -> str:
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None)
    return f"{int(round(cfg.traffic.warmup_s / cfg.dt_s))} steps"


if __name__ == "__main__":
    sys.exit(main())
