"""What one in-process run costs beside its stepping: its peak memory at two run lengths
(``scripts/bench_memory.py``) and what recording costs it, with the recorder's write path
(``scripts/bench_recording.py``); each figure against a reference measured by the same script
(docs/input-limits.md, docs/performance.md: its figures in the CHANGELOG). Figures only; nothing is asserted.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MEMORY_CHILD = r"""
import json, resource, sys, time
from evoscen_bringup.inprocess import run_inprocess
from evoscen_sim.config.scenario_config import load_scenario_config
steps, bvs = int(sys.argv[1]), int(sys.argv[2])
over = {"steps": steps, "bvs.count": bvs, "spawn.ramp_vehicles": min(3, bvs)}
cfg = load_scenario_config(None, over)
rss = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
base = rss()
marks = {}
def progress(k):
    if k == steps:
        marks["sim"] = rss()
t0 = time.perf_counter()
summary = run_inprocess(cfg, bag_dir=None, evaluate=True, progress=progress)
print(json.dumps({"steps": steps, "base": base, "sim": marks.get("sim", 0), "scored": rss(),
                  "wall_s": time.perf_counter() - t0}))
"""
"""A fresh process's scored run of ``argv[1]`` steps among ``argv[2]`` BVs: its peak RSS (``ru_maxrss``)
before, after the simulation and after the scoring, as one JSON line."""

TRACE_CHILD = r"""
import sys, tracemalloc
from pathlib import Path
from evoscen_bringup import inprocess
from evoscen_sim.config.scenario_config import load_scenario_config
steps, bvs = int(sys.argv[1]), int(sys.argv[2])
cfg = load_scenario_config(None, {"steps": steps, "bvs.count": bvs, "spawn.ramp_vehicles": min(3, bvs)})
snaps = {}
def progress(k):
    if k == steps:
        snaps["sim"] = tracemalloc.take_snapshot()
        tracemalloc.reset_peak()
tracemalloc.start(4)
summary = inprocess.run_inprocess(cfg, bag_dir=None, evaluate=True, progress=progress)
cur, peak = tracemalloc.get_traced_memory()
snaps["scored"] = tracemalloc.take_snapshot()
print(f"traced after scoring: {cur / 2**20:.1f} MiB; peak during scoring: {peak / 2**20:.1f} MiB "
      f"({peak / steps:.0f} B/step)")
for name, snap in snaps.items():
    stats = snap.statistics("lineno")
    total = sum(s.size for s in stats)
    print(f"\n{name}: {total / 2**20:.1f} MiB traced ({total / steps:.0f} B/step); largest sites:")
    for s in stats[:8]:
        fr = s.traceback[0]
        print(f"  {s.size / 2**20:8.2f} MiB  {s.size / steps:7.0f} B/step  {Path(fr.filename).name}:{fr.lineno}")
"""
"""A fresh process's scored run under :mod:`tracemalloc`: the allocation sites that hold the most memory
at the end of the simulation and the peak of the scoring, printed."""


WORLDS_CHILD = r"""
import json, resource, sys, time
from evoscen_bringup.inprocess import run_plans
from evoscen_bringup.plan import plan_of
from evoscen_bringup.starts import StartCache
from evoscen_experiments.experiments import config_loader
from evoscen_sut.mutants import mutant_overrides, mutants_for
worlds, steps, per_seed = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
load = config_loader(None)
variants = [{"sut.model": "mobil"}] + [mutant_overrides("mobil", m) for m in mutants_for("mobil")]
rss = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
base = rss()
cache = StartCache(size=worlds)
plans = []
for k in range(worlds):  # a sensitivity design: per_seed variants of each seed, from its shared start
    cfg = load({**variants[k % per_seed % len(variants)], "seed": str(1033000 + k // per_seed), "steps": str(steps),
                "recording.enabled": "false"})
    plans.append(plan_of(cfg, recorded=False, scenario=cache.scenario(cfg, partitioned=False)))
built = rss()
t0 = time.perf_counter()
results = run_plans(plans)
wall = time.perf_counter() - t0
failed = sum(isinstance(r, Exception) for r in results)
print(json.dumps({"worlds": worlds, "base": base, "built": built, "peak": rss(), "wall_s": wall, "failed": failed}))
"""
"""A fresh process's ``argv[1]`` scored worlds without a bag (MOBIL and its mutants, ``argv[3]`` per seed), stepped
``argv[2]`` steps in lockstep (:func:`evoscen_bringup.inprocess.run_plans`): its peak RSS before, once they are built
and at the end, as one JSON line."""


def worlds_memory(worlds: int, steps: int, per_seed: int = 12) -> None:
    """``scripts/bench_memory.py --worlds N``: the peak memory of ``worlds`` worlds stepped in lockstep in one
    process against one world alone (:data:`WORLDS_CHILD`, each a fresh process), the memory per world, printed."""
    from evoscen_experiments.bench import child_env

    def peaks(n: int) -> dict:
        out = subprocess.run([sys.executable, "-c", WORLDS_CHILD, str(n), str(steps), str(per_seed)], check=True,
                             env=child_env(), capture_output=True, text=True)
        return json.loads(out.stdout.strip().splitlines()[-1])

    one, many = peaks(1), peaks(worlds)
    mib = 2**20
    per_world = (many["peak"] - one["peak"]) / max(worlds - 1, 1)
    print(f"bench_memory --worlds: scored worlds without a bag (MOBIL and its mutants, {per_seed} per seed, shared "
          f"starts), {steps} steps in lockstep in one process; RSS = ru_maxrss (peak)")
    for r in (one, many):
        print(f"  {r['worlds']:>5} world(s): peak {r['peak'] / mib:8.1f} MiB (built {r['built'] / mib:.1f}, at import "
              f"{r['base'] / mib:.1f}); stepped in {r['wall_s']:.1f} s, {r['failed']} failed")
    print(f"  per world: {per_world / mib:.2f} MiB above one world; {worlds} worlds in {many['peak'] / 2**30:.2f} GiB "
          f"(target <= 4 GiB for 1,000)")


def _child(code: str, steps: int, bvs: int, **kwargs) -> subprocess.CompletedProcess:
    from evoscen_experiments.bench import child_env

    return subprocess.run([sys.executable, "-c", code, str(steps), str(bvs)], check=True, env=child_env(), **kwargs)


def memory_peaks(steps: int, bvs: int) -> dict:
    """The peaks of :data:`MEMORY_CHILD` for a run of ``steps`` steps among ``bvs`` BVs."""
    out = _child(MEMORY_CHILD, steps, bvs, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def memory(lengths: list[int], bvs: int, tracemalloc_steps: int | None = None) -> None:
    """``scripts/bench_memory.py``: the peaks of a 1-step run and of runs of the two ``lengths``, the bytes
    per step above the 1-step baseline, the marginal bytes per step and the ratio of the peaks, printed;
    with ``tracemalloc_steps`` the allocation sites of a run of that length instead (:data:`TRACE_CHILD`)."""
    if tracemalloc_steps:
        _child(TRACE_CHILD, tracemalloc_steps, bvs)
        return
    idle = memory_peaks(1, bvs)
    rows = [memory_peaks(n, bvs) for n in lengths]
    mib = 2**20
    print(f"bench_memory: in-process run + scoring, {bvs} BVs, no bag; RSS = ru_maxrss (peak)")
    print(f"  1-step baseline: peak {idle['scored'] / mib:.1f} MiB")
    for r in rows:
        print(f"  {r['steps']:>7} steps: peak after simulation {r['sim'] / mib:7.1f} MiB, after scoring "
              f"{r['scored'] / mib:7.1f} MiB; above baseline {(r['scored'] - idle['scored']) / r['steps']:7.0f} B/step "
              f"(wall {r['wall_s']:.1f} s)")
    a, b = rows
    dn = b["steps"] - a["steps"]
    print(f"  marginal: simulation {(b['sim'] - a['sim']) / dn:.0f} B/step, with scoring "
          f"{(b['scored'] - a['scored']) / dn:.0f} B/step")
    print(f"  peak ratio {b['steps']}/{a['steps']} steps: {b['scored'] / a['scored']:.2f} "
          f"(length ratio {b['steps'] / a['steps']:.1f})")


def recording(steps: int, repeats: int, bv_driver: str) -> None:
    """``scripts/bench_recording.py``: :func:`recorded_ratio`, then :func:`write_path` of the first recorded
    run's messages, printed. Positive counts are checked here (a one-line InputError)."""
    from evoscen_sim.config.scenario_config import load_scenario_config
    from evoscen_sim.errors import InputError

    for name, value in (("steps", steps), ("repeats", repeats)):
        if value < 1:
            raise InputError(f"--{name} = {value}: expected a positive integer")
    cfg = load_scenario_config(None, {"steps": steps, "bvs.driver": bv_driver})
    work = Path(tempfile.mkdtemp(prefix="bench_recording_"))
    recorded_ratio(cfg, steps, repeats, bv_driver, work)
    write_path(cfg, work)


def recorded_ratio(cfg, steps: int, repeats: int, bv_driver: str, work: Path) -> None:
    """``run_inprocess`` of ``cfg`` (``steps`` steps, BVs driven by ``bv_driver``) without a bag, with one
    written inline and with one written by the forked writer process (``bag_writer="process"``), alternated
    ``repeats`` times (the bags under ``work``): the steps/s of each (wall time from the call until the bag
    is closed), the ratios (median over the repeats; target >= 0.5) and whether the two bags of each repeat
    are byte-identical, printed."""
    from evoscen_bringup.inprocess import run_inprocess

    run_inprocess(cfg, bag_dir=None, steps=200)  # compile the kernels first
    off, inline, proc = [], [], []
    same = True
    for r in range(repeats):
        t0 = time.perf_counter()
        run_inprocess(cfg, bag_dir=None)
        off.append(steps / (time.perf_counter() - t0))
        for writer, rates in (("inline", inline), ("process", proc)):
            t0 = time.perf_counter()
            run_inprocess(cfg, bag_dir=work / f"{writer}{r}" / "bag", bag_writer=writer)
            rates.append(steps / (time.perf_counter() - t0))
        same &= ((work / f"inline{r}" / "bag" / "bag_0.mcap").read_bytes()
                 == (work / f"process{r}" / "bag" / "bag_0.mcap").read_bytes())
        print(f"  repeat {r + 1}: unrecorded {off[-1]:8.0f} steps/s   recorded inline {inline[-1]:7.0f} "
              f"(ratio {inline[-1] / off[-1]:.2f})   recorded by the writer process {proc[-1]:7.0f} "
              f"(ratio {proc[-1] / off[-1]:.2f})")
    med = statistics.median
    print(f"in-process, 1 SUT + 20 BVs ({bv_driver}), {steps} steps, median of {repeats}: "
          f"unrecorded {med(off):.0f} steps/s; recorded inline {med(inline):.0f} steps/s, "
          f"recorded / unrecorded {med([b / a for a, b in zip(off, inline)]):.2f}; recorded by the writer process "
          f"{med(proc):.0f} steps/s, recorded / unrecorded {med([b / a for a, b in zip(off, proc)]):.2f} "
          f"(target >= 0.5); bags byte-identical: {'yes' if same else 'NO'}")


def write_path(cfg, work: Path) -> None:
    """The messages of the bag ``work/inline0/bag``, written again by :class:`evoscen_record.recorder.BagRecorder`
    three ways: the default (the recorder keeps the open chunk), ``chunk_writes=False`` (one ``pack`` per
    message record into the library's chunk builder) and ``fast_writes=False`` (the mcap library's own
    ``Writer.add_message``): microseconds per message of each (best of two, the bag opened and closed), their
    ratio to the library's and whether the files are byte-identical, printed."""
    from evoscen_contract.topics import contract_for
    from evoscen_eval.scenes.clips import read_messages
    from evoscen_record.recorder import BagRecorder
    from evoscen_sim.nodes.bv_nodes import bv_nodes

    contract = contract_for([n.name for n in bv_nodes(cfg)])  # the run's topics: one command topic per BV node

    messages = read_messages(work / "inline0" / "bag")
    paths = {"chunk": {}, "fast": {"chunk_writes": False}, "library": {"fast_writes": False}}
    per_message: dict[str, list[float]] = {}
    files = {}
    for rep in range(2):
        for path, kwargs in paths.items():
            name = f"{path}{rep}"
            t0 = time.perf_counter()
            bag = BagRecorder(work / name / "bag", contract, compression=cfg.recording.compression,
                              chunk_size=cfg.recording.chunk_size_bytes, **kwargs)
            for topic, t_ns, data in messages:
                bag.write(topic, data, t_ns, canonical=True)
            bag.close()
            per_message.setdefault(path, []).append((time.perf_counter() - t0) / len(messages) * 1e6)
            files[name] = (work / name / "bag" / "bag_0.mcap").read_bytes()
    us = {path: min(v) for path, v in per_message.items()}
    same = len(set(files.values())) == 1
    print(f"BagRecorder.write of the run's {len(messages)} messages: chunk writes {us['chunk']:.1f} us/message, "
          f"fast_writes {us['fast']:.1f}, mcap's add_message {us['library']:.1f}; "
          f"ratio to the library {us['chunk'] / us['library']:.2f} / {us['fast'] / us['library']:.2f}; "
          f"files byte-identical: {'yes' if same else 'NO'}")
