"""The profiles of ``scripts/profile_episodes.py``, ``scripts/sut_step_cost.py`` and
``scripts/profile_entries.py``: where an experiment episode's time goes, the SUT drivers' CPU time per
step, and what the traffic window's entries cost a step (docs/performance.md "Experiments" and "Current
figures"). Each times the functions that do the work by wrapping them for the run, and puts them back.
"""

from __future__ import annotations

import copy
import json
import time
import timeit

FIRST_SEED = 96000
"""First seed of the profiled episodes (any: the figures do not depend on it)."""
START = "start: the seed's first built (warm-up, BV driver), the others copied"
SCENARIOS = ("evolving", "level0", "nilsson", "mobil")
"""The scenarios of ``profile_episodes.py --scenario``: the evolving BVs, or all BVs driven by one model."""


def mutant_names(option: str, text: str) -> list[str]:
    """The mutants of MOBIL that ``text`` names: ``all`` (every mutant of the library) or distinct
    comma-separated names of it (else a one-line InputError naming ``option``)."""
    from evoscen_experiments.experiments import distinct_names
    from evoscen_sim.errors import InputError
    from evoscen_sut.mutants import LIBRARY

    mutants = list(LIBRARY) if text.strip() == "all" else distinct_names(option, text)
    unknown = [m for m in mutants if m not in LIBRARY]
    if unknown:
        raise InputError(f"{option}: unknown mutant {unknown[0]!r}: expected 'all' or names from {', '.join(LIBRARY)}")
    return mutants


def profile_episodes(scenario: str, seeds: str, mutants: str, episode_steps: str) -> int:
    """``scripts/profile_episodes.py`` with its options' text: checked (a one-line InputError), profiled
    (:func:`profile`); the exit status: 0, 1 when the two ways' reports differ."""
    from evoscen_contract.contract import EXIT_OK
    from evoscen_experiments.experiments import positive_int
    from evoscen_sim.errors import InputError

    if scenario not in SCENARIOS:
        raise InputError(f"--scenario {scenario!r}: expected one of {', '.join(SCENARIOS)}")
    n_seeds = positive_int("--seeds", seeds)
    steps = positive_int("--episode-steps", episode_steps)
    return EXIT_OK if profile(scenario, n_seeds, mutant_names("--mutants", mutants), steps) else 1


def profile(scenario: str, seeds: int, mutants: list[str], steps: int) -> bool:
    """MOBIL and ``mutants`` on ``seeds`` seeds from :data:`FIRST_SEED` (``steps`` scored steps each, no bag) two
    ways, alternated seed by seed: *per run* (every episode built from scratch: the file parsed, the warm-up,
    the BV drivers of every BV node) and *shared start* (the file parsed once, the warm-up and one BV driver
    built once per seed and copied for every variant, :mod:`evoscen_bringup.starts`). Prints per episode the
    wall time of each phase and the speed-up; True when both ways' reports are the same (JSON, byte for byte)."""
    import evoscen_sim.loop.step_loop as step_loop
    from evoscen_bringup import inprocess, starts
    from evoscen_bringup import scenario as scenario_mod
    from evoscen_experiments.experiments import Round, config_loader
    from evoscen_sim import scenario_builders
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sut.mutants import mutant_overrides

    phases: dict[str, float] = {}
    patched: list[tuple[object, str, object]] = []

    def timed(owner, name: str, label: str) -> None:
        inner = getattr(owner, name)
        patched.append((owner, name, inner))

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

    totals: dict[str, dict[str, float]] = {"per run": {}, "shared start": {}}
    same = True
    try:
        per_run(FIRST_SEED - 1)  # compiled kernels loaded, files cached: not timed
        shared(FIRST_SEED - 1)
        for k in range(seeds):
            order = (("per run", per_run), ("shared start", shared))
            reports = {}
            for name, fn in order if k % 2 == 0 else order[::-1]:
                phases.clear()
                t = time.perf_counter()
                reports[name] = fn(FIRST_SEED + k)
                phases["total"] = time.perf_counter() - t
                for label, s in phases.items():
                    totals[name][label] = totals[name].get(label, 0.0) + s
            same = same and reports["per run"] == reports["shared start"]
    finally:
        for owner, name, inner in reversed(patched):
            setattr(owner, name, inner)
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


def sut_step_lines(mutants: list[str], repeats: int, steps: int) -> list[str]:
    """MOBIL and each of ``mutants`` as the sensitivity experiment runs its episodes (evolving scenario, from
    a shared start, no bag, scored, one process), ``repeats`` times in turn (seeds from :data:`FIRST_SEED`)
    after one untimed round: the report's lines, per variant the CPU time (``time.process_time``: less
    sensitive than wall time to other processes) per step of the SUT driver's ``act`` and of the scored step
    loop, and each variant's ``act`` over MOBIL's."""
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


def sut_step_cost(mutants: str, repeats: str, episode_steps: str) -> None:
    """``scripts/sut_step_cost.py`` with its options' text: checked (a one-line InputError), measured and
    printed (:func:`sut_step_lines`)."""
    from evoscen_experiments.experiments import positive_int

    n = positive_int("--repeats", repeats)
    steps = positive_int("--episode-steps", episode_steps)
    for line in sut_step_lines(mutant_names("--mutants", mutants), n, steps):
        print(line)





def profile_entries(seed: str, driver: str, blocks: str, block_steps: str, repeats: str) -> None:
    """``scripts/profile_entries.py`` with its options' text: checked (a one-line InputError), then the
    tries per step of each block and the time of one try, printed (:func:`entries`)."""
    from evoscen_experiments.experiments import positive_int
    from evoscen_sim.errors import InputError

    seed_n = positive_int("--seed", seed, 0)
    blocks_n = positive_int("--blocks", blocks)
    block_steps_n = positive_int("--block-steps", block_steps)
    repeats_n = positive_int("--repeats", repeats)
    if driver not in ("level0", "learned"):
        raise InputError(f"--driver {driver!r}: expected level0 or learned")
    entries(seed_n, driver, blocks_n, block_steps_n, repeats_n)


def entries(seed: int, driver: str, blocks: int, block_steps: int, repeats: int) -> None:
    """The default scenario (recording off, one BV driver) after 300 steps: per block of ``block_steps``
    steps the entry tries per step (:meth:`evoscen_sim.physics.window.TrafficWindow._enter` calls) and the
    block's time per step; then the time of one try that finds no place (the first vehicle outside the
    window at the end, tried ``repeats`` times from the same state and random stream, best of three)."""
    import numpy as np
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.physics.window import TrafficWindow

    steps = blocks * block_steps + 300
    cfg = load_scenario_config(None, {"seed": seed, "bvs.driver": driver, "recording.enabled": False,
                                      "steps": steps, "bvs.nodes": "single"})
    sc = build_scenario(cfg)
    for _ in range(300):  # kernels compiled, traffic settled
        sc.step()
    tries = [0]
    enter = TrafficWindow._enter

    def counted(self, world, i):
        tries[0] += 1
        return enter(self, world, i)

    TrafficWindow._enter = counted
    try:
        for b in range(blocks):
            tries[0] = 0
            t0 = time.perf_counter()
            for _ in range(block_steps):
                sc.step()
            us = (time.perf_counter() - t0) / block_steps * 1e6
            print(f"block {b}: {tries[0] / block_steps:.2f} entry tries per step, {us:.0f} us per step "
                  f"(the counter included)")
    finally:
        TrafficWindow._enter = enter
    world = sc.world
    p = world.window.p
    for _ in range(3000):  # a state with a vehicle outside the window that finds no place (tried on a copy)
        s = world.s
        s_sut = float(s[world.window.sut])
        out = [int(k) for k in np.flatnonzero((s < s_sut - p.behind_m - p.exit_margin_m)
                                              | (s > s_sut + p.ahead_m + p.exit_margin_m)) if k != world.window.sut]
        if out:
            trial, i = copy.deepcopy(world), out[0]
            state = trial.rng.bit_generator.state
            if trial.window._enter(trial, i) is None:
                break
        sc.step()
    else:
        print("no vehicle outside the window failed to enter in 3,000 steps: no single try timed")
        return

    def one_try():
        trial.rng.bit_generator.state = state
        return trial.window._enter(trial, i)

    best = min(timeit.repeat(one_try, number=repeats, repeat=3)) / repeats * 1e6
    print(f"one try that finds no place (vehicle {i}): {best:.1f} us (best of 3 x {repeats})")
