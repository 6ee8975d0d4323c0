#!/usr/bin/env python3
"""What recording costs an in-process run, and what the recorder's write path costs.

    python scripts/bench_recording.py [--steps N] [--repeats R] [--bv-driver level0|learned]

Two figures, each against a reference measured in the same process (these machines are
shared and noisy: compare ratios, not absolute rates):

1. **Recorded / unrecorded** (issue 14's figure): ``run_inprocess`` of the default scenario for
   ``--steps`` steps without a bag, with one written inline (between the steps) and with one
   written by the forked writer process (``bag_writer="process"``, the default where more than
   one CPU is usable; docs/recording.md), the three alternated ``--repeats`` times; steps/s of
   each (wall time from the call until the bag is closed) and the ratios (median over the
   repeats). Target: >= 0.5. The two bags of a repeat are compared byte for byte.
2. **The write path**: the messages of one recorded run, read back from its bag, written again
   by :class:`evoscen_record.recorder.BagRecorder` three ways: the default (the recorder keeps the
   open chunk, ``mcap_internals.ChunkMessages``), ``chunk_writes=False`` (one ``pack`` per message record into
   the library's chunk builder, ``mcap_internals.FastMessages``) and ``fast_writes=False`` (the mcap library's
   own ``Writer.add_message``); microseconds per message of each (best of two, bag opening and
   closing included), their ratio to the library's, and whether the files are byte-identical.

Figures only; nothing is asserted (benchmarks print figures; the tests assert the bytes).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_OK


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench_recording.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=3000, help="steps per run (default 3000)")
    ap.add_argument("--repeats", type=int, default=5, help="alternated unrecorded/recorded pairs (default 5)")
    ap.add_argument("--bv-driver", choices=("level0", "learned"), default="level0")
    args = ap.parse_args(argv)
    for name in ("steps", "repeats"):
        if getattr(args, name) < 1:
            print(f"error: --{name} = {getattr(args, name)}: expected a positive integer", file=sys.stderr)
            return EXIT_BAD_INPUT

    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_contract.topics import CONTRACT
    from evoscen_eval.scenes.clips import read_messages
    from evoscen_record.recorder import BagRecorder
    from evoscen_sim.config.scenario_config import load_scenario_config

    cfg = load_scenario_config(None, {"steps": args.steps, "bvs.driver": args.bv_driver})
    run_inprocess(cfg, bag_dir=None, steps=200)  # compile the kernels first
    work = Path(tempfile.mkdtemp(prefix="bench_recording_"))
    off, inline, proc = [], [], []
    same = True
    for r in range(args.repeats):
        t0 = time.perf_counter()
        run_inprocess(cfg, bag_dir=None)
        off.append(args.steps / (time.perf_counter() - t0))
        for writer, rates in (("inline", inline), ("process", proc)):
            t0 = time.perf_counter()
            run_inprocess(cfg, bag_dir=work / f"{writer}{r}" / "bag", bag_writer=writer)
            rates.append(args.steps / (time.perf_counter() - t0))
        same &= ((work / f"inline{r}" / "bag" / "bag_0.mcap").read_bytes()
                 == (work / f"process{r}" / "bag" / "bag_0.mcap").read_bytes())
        print(f"  repeat {r + 1}: unrecorded {off[-1]:8.0f} steps/s   recorded inline {inline[-1]:7.0f} "
              f"(ratio {inline[-1] / off[-1]:.2f})   recorded by the writer process {proc[-1]:7.0f} "
              f"(ratio {proc[-1] / off[-1]:.2f})")
    med = statistics.median
    print(f"in-process, 1 SUT + 20 BVs ({args.bv_driver}), {args.steps} steps, median of {args.repeats}: "
          f"unrecorded {med(off):.0f} steps/s; recorded inline {med(inline):.0f} steps/s, "
          f"recorded / unrecorded {med([b / a for a, b in zip(off, inline)]):.2f}; recorded by the writer process "
          f"{med(proc):.0f} steps/s, recorded / unrecorded {med([b / a for a, b in zip(off, proc)]):.2f} "
          f"(target >= 0.5); bags byte-identical: {'yes' if same else 'NO'}")

    messages = read_messages(work / "inline0" / "bag")
    paths = {"chunk": {}, "fast": {"chunk_writes": False}, "library": {"fast_writes": False}}
    per_message: dict[str, list[float]] = {}
    files = {}
    for rep in range(2):
        for path, kwargs in paths.items():
            name = f"{path}{rep}"
            t0 = time.perf_counter()
            bag = BagRecorder(work / name / "bag", CONTRACT, compression=cfg.recording.compression,
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
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
