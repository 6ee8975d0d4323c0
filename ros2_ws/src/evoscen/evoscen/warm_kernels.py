"""Compile evoscen's kernels into numba's cache before the first run needs them.

The per-step kernels (:mod:`evoscen_sim.jit`) are compiled at their first call with the argument types
of that call and cached on disk (``__pycache__/*.nbi, *.nbc`` next to their modules); every later
process, a Ray worker included, loads them from there. ``make build`` drops that cache after a rebuild,
and a fresh clone has none: without this step the first experiment's workers compile all of them
(about a minute each, in parallel). :func:`warm` runs short in-process scenarios that call the kernels
with the argument types the runs use — learned BVs under both traffic make-ups, level-0 BVs, each
built-in SUT decision model, scoring — so they are compiled once, here, or loaded when already cached.
Nothing is written but the cache. ``python scripts/warm_kernels.py`` runs it; ``make build`` after a rebuild.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

STEPS = 300
"""Steps of each warm-up run. [choice] 300: the forced merges of the ramp's vehicles come after step 100."""

RUNS: tuple[dict[str, object], ...] = tuple(
    {"bvs.makeup": makeup, "bvs.driver": driver, "sut.model": sut, "seed": seed}
    for seed, (makeup, driver, sut) in enumerate(
        [(m, d, s) for m in ("highd", "uniform") for d in ("learned", "level0")
         for s in ("level0", "mobil", "nilsson", "stackelberg")], start=1)
) + ({"traffic.mode": "loop", "bvs.makeup": "uniform", "sut.model": "mobil", "seed": 1},)
"""The runs, each with these overrides of the shipped scenario: every pair of make-up, BV driver and SUT
model, then the loop traffic mode (the others run the traffic window)."""

PACKAGES = ("evoscen_contract", "evoscen_sim", "evoscen_bv", "evoscen_sut", "evoscen_record", "evoscen_eval",
            "evoscen_bringup", "evoscen_experiments", "evoscen")


@dataclass(frozen=True)
class KernelCount:
    """The compiled kernels of the imported evoscen modules after the runs."""

    run: tuple[str, ...]
    """Kernels with at least one compiled (or cache-loaded) signature."""
    not_run: tuple[str, ...]
    """The others: kernels called only inside other kernels (compiled into them: from the cache, their
    callers load without them), or on paths no run took (compiled at their first call)."""
    signatures: int


def kernels(modules=None) -> dict[str, object]:
    """``module.name`` -> numba dispatcher of every kernel defined in the imported evoscen modules
    (``modules``: a mapping of module name to module, ``sys.modules`` by default)."""
    from numba.core.registry import CPUDispatcher
    from numba.np.ufunc.dufunc import DUFunc

    out = {}
    for mod_name, mod in list((sys.modules if modules is None else modules).items()):
        if mod is None or mod_name.split(".")[0] not in PACKAGES:
            continue
        for name, obj in list(vars(mod).items()):
            if isinstance(obj, (CPUDispatcher, DUFunc)) and getattr(obj, "__module__", mod_name) == mod_name:
                out[f"{mod_name}.{name}"] = obj
    return out


def count(found: dict[str, object]) -> KernelCount:
    """Which of ``found`` (:func:`kernels`) have a compiled signature, and how many signatures in all."""
    run, not_run, n = [], [], 0
    for name, disp in sorted(found.items()):
        sigs = len(getattr(disp, "signatures", None) or getattr(disp, "types", None) or ())
        (run if sigs else not_run).append(name)
        n += sigs
    return KernelCount(tuple(run), tuple(not_run), n)


WAYS = ("fresh", "by BV node", "shared start")
"""How each run is built (the argument types differ: a shared start's copies hold writable copies of the
road's read-only tables, a BV node's driver its share of the vehicles): ``fresh`` as ``run_scenario.py``
without a bag (one driver of all BVs), ``by BV node`` as a recorded run, ``shared start`` as an
experiment's worker (:class:`evoscen_bringup.starts.StartCache`)."""


def warm(steps: int = STEPS, runs=RUNS, say=print) -> KernelCount:
    """Run each of ``runs`` for ``steps`` steps, scored, every way of :data:`WAYS`, and the first once more
    with a bag (in a temporary directory, removed); returns the kernels' count (:func:`count`)."""
    import tempfile
    from pathlib import Path

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.scenario import build_scenario
    from evoscen_bringup.starts import StartCache
    from evoscen_sim.config.scenario_config import load_scenario_config

    t0 = time.perf_counter()
    starts = StartCache()
    for i, overrides in enumerate(runs, 1):
        t = time.perf_counter()
        cfg = load_scenario_config(None, {**overrides, "steps": steps})
        for way in WAYS:
            scenario = (starts.scenario(cfg, partitioned=False) if way == "shared start"
                        else build_scenario(cfg, partitioned=way == "by BV node"))
            _check(run_inprocess(cfg, bag_dir=None, scenario=scenario, evaluate=True, plots=False), steps, overrides)
        if i == 1:
            with tempfile.TemporaryDirectory(prefix="evoscen-warm-") as tmp:
                _check(run_inprocess(cfg, bag_dir=Path(tmp) / "bag", evaluate=True, plots=False, bag_writer="inline"),
                       steps, overrides)
        say(f"  {i:2d}/{len(runs)} {_label(overrides)}: {time.perf_counter() - t:.1f} s")
    c = count(kernels())
    say(f"kernels: {len(c.run)} of {len(c.run) + len(c.not_run)} compiled or loaded from the cache ({c.signatures} "
        f"signatures; the others run inside them), {time.perf_counter() - t0:.1f} s")
    return c


def _check(summary, steps: int, overrides) -> None:
    if summary.steps != steps:
        raise RuntimeError(f"warm-up run {_label(overrides)}: {summary.steps} of {steps} steps")


def _label(overrides: dict[str, object]) -> str:
    return ", ".join(f"{k}={v}" for k, v in overrides.items() if k != "seed")
