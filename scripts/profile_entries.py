#!/usr/bin/env python3
"""What the traffic window's entries cost a step: tries per step and the time of one try.

    python scripts/profile_entries.py [--seed 3] [--driver level0|learned] [--blocks 4] [--block-steps 1500]
                                      [--repeats 3000]

Runs the default scenario (recording off, one BV driver) and prints, per block of ``--block-steps``
steps, the entry tries per step (:meth:`evoscen_sim.physics.window.TrafficWindow._enter` calls:
vehicles that left the window, each trying to enter again) and the block's time per step; then the time
of one try that finds no place (the first vehicle outside the window at the end, tried ``--repeats``
times from the same state and random stream, best of three). Figures for docs/performance.md; run it on
two versions to compare them (the same seed gives the same world). Exit status: 0, 2 bad input.
"""

from __future__ import annotations

import argparse
import sys
import time
import timeit

import _bootstrap  # noqa: F401
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", default="3")
    ap.add_argument("--driver", default="level0")
    ap.add_argument("--blocks", default="4")
    ap.add_argument("--block-steps", default="1500")
    ap.add_argument("--repeats", default="3000")
    try:
        args = ap.parse_args(argv)
    except SystemExit as exc:
        return EXIT_OK if exc.code == 0 else EXIT_BAD_INPUT
    from evoscen_experiments.experiments import positive_int
    from evoscen_sim.errors import InputError

    try:
        for name in ("seed", "blocks", "block_steps", "repeats"):
            setattr(args, name, positive_int(f"--{name.replace('_', '-')}", getattr(args, name),
                                             0 if name == "seed" else 1))
        if args.driver not in ("level0", "learned"):
            raise InputError(f"--driver {args.driver!r}: expected level0 or learned")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT

    import numpy as np
    from evoscen_bringup.scenario import build_scenario
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.physics.window import TrafficWindow

    steps = args.blocks * args.block_steps + 300
    cfg = load_scenario_config(None, {"seed": args.seed, "bvs.driver": args.driver, "recording.enabled": False,
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
        for b in range(args.blocks):
            tries[0] = 0
            t0 = time.perf_counter()
            for _ in range(args.block_steps):
                sc.step()
            us = (time.perf_counter() - t0) / args.block_steps * 1e6
            print(f"block {b}: {tries[0] / args.block_steps:.2f} entry tries per step, {us:.0f} us per step "
                  f"(the counter included)")
    finally:
        TrafficWindow._enter = enter
    import copy

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
        return EXIT_OK

    def one_try():
        trial.rng.bit_generator.state = state
        return trial.window._enter(trial, i)

    best = min(timeit.repeat(one_try, number=args.repeats, repeat=3)) / args.repeats * 1e6
    print(f"one try that finds no place (vehicle {i}): {best:.1f} us (best of 3 x {args.repeats})")
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
