"""Where a step's time goes between compiled work and what surrounds it (``scripts/profile_kernels.py``).

A step of evoscen is Python that calls compiled kernels (:mod:`evoscen_sim.jit`). Its wall time splits into

* **compute**: the kernels' own work, measured by calling each kernel again from a compiled loop on copies of
  arguments it was given in the run (no dispatch, no boxing, the caller's arrays untouched), warm: a low
  estimate of the time inside the kernel;
* **call overhead**: the kernels' calls as Python sees them less their compute (the dispatcher's typing of the
  arguments, unboxing every array, boxing every array returned, and whatever the warm measurement misses);
* **Python**: the rest of the step (the drivers' and the loop's code between the calls).

Compute is what the kernels would cost if nothing surrounded them; the issue of many worlds at once asks how
much of the rest one call for many worlds removes (docs/performance.md "Where a step's time goes").

:class:`KernelProfile` replaces, while it is open, every binding of a compiled dispatcher in the loaded modules
whose names start with one of its prefixes by a timing wrapper and puts each back on exit. Only calls made
from Python are seen: a kernel that calls another runs it compiled, inside its own time.
"""

from __future__ import annotations

import sys
import time
from collections import Counter, defaultdict
from dataclasses import dataclass

import numpy as np

SAMPLE_EVERY = 25
"""A call's arguments are kept for the compute measurement once in this many calls of its kernel."""
MAX_SAMPLES = 60
"""At most this many kept calls per kernel are measured."""
COMPUTE_REPEATS = 10
"""Each kept call is run this many times in a block from the compiled loop (after one untimed run)."""
COMPUTE_BLOCKS = 3
"""Blocks per kept call; its compute is the least block's mean."""


def copied(value):
    """``value`` with every array copied (plain tuples taken apart; a named tuple or anything else as it is)."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if type(value) is tuple:
        return tuple(copied(v) for v in value)
    return value


_LOOPS: dict[int, object] = {}


def compiled_loop(arity: int):
    """A compiled ``loop(f, n, a0, ..., a{arity-1})`` that calls the compiled ``f`` ``n`` times (made once per arity)."""
    if arity not in _LOOPS:
        import numba

        names = ", ".join(f"a{i}" for i in range(arity))
        namespace: dict = {}
        exec(f"def loop(f, n{', ' if names else ''}{names}):\n    for _ in range(n):\n        f({names})\n    return 0",
             namespace)
        _LOOPS[arity] = numba.njit(namespace["loop"])
    return _LOOPS[arity]


@dataclass
class KernelRow:
    """One kernel's share of the profiled steps (per step: calls, µs of calls, µs of compute)."""

    name: str
    calls: float
    call_us: float
    compute_us: float


class KernelProfile:
    """Times every call of a compiled kernel made from Python while open (module docstring).

    Args:
        prefixes: the modules whose bindings are wrapped (names starting with one of them).
        sample_every: keep one call's arguments in this many (:data:`SAMPLE_EVERY`).
    """

    def __init__(self, prefixes: tuple[str, ...] = ("evoscen",), sample_every: int = SAMPLE_EVERY) -> None:
        if sample_every < 1:
            raise ValueError(f"sample_every must be >= 1, got {sample_every}")
        self.prefixes = tuple(prefixes)
        self.sample_every = int(sample_every)
        self.calls: Counter[str] = Counter()
        self.call_s: defaultdict[str, float] = defaultdict(float)
        self.samples: defaultdict[str, list] = defaultdict(list)
        self.own_s = 0.0
        """Seconds the profile spent keeping arguments (copies), to be taken off the wall time of the profiled code."""
        self._dispatchers: dict[str, object] = {}
        self._bound: list[tuple[object, str, object]] = []

    def _wrapper(self, name: str, dispatcher):
        calls, call_s, samples, every = self.calls, self.call_s, self.samples, self.sample_every
        clock = time.perf_counter

        def timed(*args):
            calls[name] += 1
            if calls[name] % every == 1 or every == 1:  # the arguments as the kernel is given them
                t0 = clock()
                samples[name].append(copied(args))
                self.own_s += clock() - t0
            t0 = clock()
            out = dispatcher(*args)
            call_s[name] += clock() - t0
            return out

        timed.__wrapped__ = dispatcher  # type: ignore[attr-defined]
        return timed

    def __enter__(self) -> KernelProfile:
        from numba.core.registry import CPUDispatcher

        wrappers: dict[int, object] = {}
        for module_name, module in list(sys.modules.items()):
            if module is None or not module_name.startswith(self.prefixes):
                continue
            for attr, value in list(vars(module).items()):
                if isinstance(value, CPUDispatcher):
                    name = f"{value.py_func.__module__}.{value.py_func.__name__}"
                    if id(value) not in wrappers:
                        wrappers[id(value)] = self._wrapper(name, value)
                        self._dispatchers[name] = value
                    self._bound.append((module, attr, value))
                    setattr(module, attr, wrappers[id(value)])
        return self

    def __exit__(self, *exc) -> None:
        for module, attr, value in self._bound:
            setattr(module, attr, value)
        self._bound.clear()

    def compute_s(self, repeats: int = COMPUTE_REPEATS, max_samples: int = MAX_SAMPLES) -> dict[str, float]:
        """Per kernel: the mean seconds of one call's compute over its kept calls (after :meth:`__exit__`: the
        kernels are compiled against the modules' own bindings)."""
        if self._bound:
            raise RuntimeError("KernelProfile.compute_s: close the profile first")
        out = {}
        for name, kept in self.samples.items():
            dispatcher = self._dispatchers[name]
            times = []
            for args in kept[:max_samples]:
                loop = compiled_loop(len(args))
                loop(dispatcher, 1, *copied(args))
                blocks = []
                for _ in range(COMPUTE_BLOCKS):  # the least of a few blocks: a burst of the host's other work left out
                    fresh = copied(args)
                    t0 = time.perf_counter()
                    loop(dispatcher, repeats, *fresh)
                    blocks.append((time.perf_counter() - t0) / repeats)
                times.append(min(blocks))
            out[name] = float(np.mean(times))
        return out

    def rows(self, steps: int, compute: dict[str, float] | None = None) -> list[KernelRow]:
        """Per kernel, per step of ``steps``: calls, µs in its calls, µs of compute (its calls × its mean compute);
        most time first."""
        if steps < 1:
            raise ValueError(f"steps must be >= 1, got {steps}")
        compute = self.compute_s() if compute is None else compute
        rows = [KernelRow(name, n / steps, self.call_s[name] / steps * 1e6, compute.get(name, 0.0) * n / steps * 1e6)
                for name, n in self.calls.items()]
        return sorted(rows, key=lambda r: (-r.call_us, r.name))


def split(wall_s: float, steps: int, rows: list[KernelRow]) -> dict[str, float]:
    """A step's µs: wall, compute, call overhead (calls less compute), Python (wall less calls)."""
    wall = wall_s / steps * 1e6
    calls = sum(r.call_us for r in rows)
    compute = sum(r.compute_us for r in rows)
    return {"wall_us": wall, "compute_us": compute, "call_overhead_us": calls - compute, "python_us": wall - calls}


def lines(title: str, wall_s: float, steps: int, rows: list[KernelRow], top: int = 12) -> list[str]:
    """The report of one profiled case: the split of a step and the kernels that take most of it."""
    s = split(wall_s, steps, rows)
    out = [f"{title}: {s['wall_us']:.1f} us a step = compute {s['compute_us']:.1f} ({s['compute_us'] / s['wall_us']:.0%})"
           f" + call overhead {s['call_overhead_us']:.1f} + Python {s['python_us']:.1f}",
           "  kernel (calls a step, us in calls, us of compute):"]
    out += [f"  {r.calls:5.2f} {r.call_us:7.2f} {r.compute_us:7.2f}  {r.name}" for r in rows[:top]]
    return out


CASES = ("highd-level0", "uniform-level0", "highd-learned", "uniform-learned", "batched")
"""The cases of ``profile_kernels.py --cases``: one world (default SUT, one BV driver, no score, as ``bench.py``'s make-up
section) under a make-up with level-0 or learned BVs, or ``batched``: scored worlds without a bag in lockstep (MOBIL SUT,
learned BVs, the shipped make-up, as ``bench.py --batched``)."""
FIRST_SEED = 97000
"""First seed of the profiled worlds (any: the split does not depend on it)."""


def _single(case: str, steps: int) -> tuple[float, int, KernelProfile]:
    from evoscen_bringup.scenario import build_scenario
    from evoscen_experiments.bench_runs import INPROCESS_WARMUP
    from evoscen_sim.config.scenario_config import load_scenario_config

    makeup, driver = case.split("-")
    cfg = load_scenario_config(None, {"bvs.driver": driver, "bvs.makeup": makeup, "bvs.nodes": "single",
                                      "seed": str(FIRST_SEED)})
    sc = build_scenario(cfg, partitioned=False)
    for _ in range(INPROCESS_WARMUP):
        sc.step()
    with KernelProfile() as prof:
        t0 = time.perf_counter()
        for _ in range(steps):
            sc.step()
        wall = time.perf_counter() - t0 - prof.own_s  # without the copies the profile keeps
    return wall, steps, prof


def _batched(worlds: int, steps: int) -> tuple[float, int, KernelProfile]:
    from evoscen_bringup.inprocess import run_plans
    from evoscen_experiments.bench_batched import batched_plans

    plans, warm = batched_plans(worlds, steps, FIRST_SEED)
    run_plans([warm])  # untimed: kernels loaded before the profile
    with KernelProfile() as prof:
        t0 = time.perf_counter()
        failed = [r for r in run_plans(plans) if isinstance(r, Exception)]
        wall = time.perf_counter() - t0 - prof.own_s  # without the copies the profile keeps
    if failed:
        raise RuntimeError(f"profile_kernels: {len(failed)} world(s) failed: {failed[0]}")
    return wall, worlds * steps, prof


def budget_lines(splits: dict[str, dict[str, float]], sumo_steps_per_s: float, jobs: int = 2) -> list[str]:
    """Each case's wall and compute beside libsumo's step (same road, its vehicles as the worlds'), and for the
    batched case the world-step that 5 x libsumo's vehicle-steps/s on ``jobs`` processes allows: ``jobs`` / (5 R)
    (equal vehicles a world and a SUMO step)."""
    step = 1e6 / sumo_steps_per_s
    out = [f"libsumo: {sumo_steps_per_s:.0f} steps/s = {step:.1f} us a step"]
    for case, s in splits.items():
        out.append(f"  {case}: wall {s['wall_us'] / step:.2f}, compute {s['compute_us'] / step:.2f} of libsumo's step")
        if case == "batched":
            allowed = jobs * step / 5.0
            out.append(f"  batched at 5x libsumo's vehicle-steps/s on {jobs} processes: {allowed:.1f} us a world-step; "
                       f"compute alone is {s['compute_us'] / allowed:.2f} of it, the step {s['wall_us'] / allowed:.2f}")
    return out


def profile_kernels(cases_text: str, steps_text: str, worlds_text: str, sumo: bool = True) -> int:
    """``scripts/profile_kernels.py`` with its options' text: checked (a one-line InputError), each case profiled
    and printed (:func:`lines`), then (``sumo`` and libsumo installed) libsumo's rate in this process and
    :func:`budget_lines`; exit status 0."""
    from evoscen_experiments.experiments import distinct_names, positive_int
    from evoscen_sim.errors import InputError

    cases = distinct_names("--cases", cases_text)
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        raise InputError(f"--cases: unknown case {unknown[0]!r}: expected names from {', '.join(CASES)}")
    steps = positive_int("--steps", steps_text)
    worlds = positive_int("--worlds", worlds_text)
    splits = {}
    for case in cases:
        if case == "batched":
            wall, n, prof = _batched(worlds, steps)
            title = f"batched: {worlds} scored worlds in lockstep, {steps} steps, per world-step"
        else:
            wall, n, prof = _single(case, steps)
            title = f"{case}: one world, {steps} steps"
        rows = prof.rows(n)
        splits[case] = split(wall, n, rows)
        for line in lines(title, wall, n, rows):
            print(line, flush=True)
    if sumo:
        from evoscen_experiments.sumo_baseline import measure_sumo_steps_per_second, sumo_available

        ok, why = sumo_available()
        if not ok:
            print(f"libsumo skipped: {why}")
            return 0
        try:
            rate = measure_sumo_steps_per_second(steps=3000, vehicles=21, seed=0, in_process=True)["steps_per_s"]
        except RuntimeError as exc:  # a failed SUMO run: the profile stands without its reference
            print(f"libsumo skipped: {str(exc).splitlines()[0]}")
            return 0
        for line in budget_lines(splits, rate):
            print(line, flush=True)
    return 0
