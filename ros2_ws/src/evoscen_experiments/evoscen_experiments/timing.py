"""An experiment command's fixed cost beside its throughput (docs/performance.md "Start-up").

:data:`COMMAND` adds up what the campaigns of this process did (:func:`evoscen_experiments.campaign.run_campaign`):
the Ray starts, the workers' first-task overhead, the runs computed and their SUT steps. :func:`finish` ends an
experiment with one line (printed) and ``timing.json`` (in its output directory)::

    wall 376 s: start-up 21 s (set-up 2 s, Ray 6 s, workers' first task 13 s), 3,900 runs × 300 SUT steps = 3,112 SUT-steps/s

* **wall** — from the process's start (its creation: the interpreter's start and the imports count) to the line;
* **set-up** — from there to the first Ray start (imports, the rounds and their keys);
* **Ray** — ``ray.init`` until it returned (every start of the command);
* **workers' first task** — per worker, the wait from the task's submission to its start on the worker plus the
  first run's time above the steady time of the same steps (:func:`first_task_overheads`: the imports, compiled
  kernels loaded from numba's cache, policies, anything a worker does once); the mean over workers, which work
  side by side;
* **SUT-steps/s** — the runs' SUT steps over the wall, the measure the progress bar shows as it goes.
"""

from __future__ import annotations

import json
import statistics
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

_IMPORTED = time.monotonic()


def process_start() -> float:
    """This process's creation on the :func:`time.monotonic` clock (this module's import time if unknown)."""
    try:
        import psutil

        return time.monotonic() - max(0.0, time.time() - psutil.Process().create_time())
    except Exception:  # noqa: BLE001 - psutil (Ray's) missing or no process table: the import time
        return _IMPORTED


@dataclass
class Timing:
    """What the campaigns of one command did, added up."""

    start: float = field(default_factory=process_start)
    ray_at: float | None = None
    """When the first Ray start began (monotonic); None without one."""
    ray_s: float = 0.0
    first_task_s: float = 0.0
    runs: int = 0
    sut_steps: int = 0
    steps: set[int] = field(default_factory=set)

    def ran(self, steps: int) -> None:
        """One run computed, of ``steps`` SUT steps."""
        self.runs += 1
        self.sut_steps += int(steps)
        self.steps.add(int(steps))

    def rates(self, now: float | None = None) -> tuple[float, float]:
        """(runs/s, SUT-steps/s) since the command started."""
        wall = max((time.monotonic() if now is None else now) - self.start, 1e-9)
        return self.runs / wall, self.sut_steps / wall

    def summary(self, now: float | None = None) -> dict[str, Any]:
        """The figures of the line (seconds, counts): see :func:`summary`."""
        now = time.monotonic() if now is None else now
        setup = (now if self.ray_at is None else self.ray_at) - self.start
        return summary(now - self.start, setup, self.ray_s, self.first_task_s, self.runs, self.sut_steps, self.steps)


COMMAND = Timing()
"""This process's command."""


def summary(wall_s: float, setup_s: float, ray_s: float, first_task_s: float, runs: int, sut_steps: int,
            steps: Iterable[int] = ()) -> dict[str, Any]:
    """The timing figures: the parts, ``startup_s`` their sum, ``sut_steps_per_s`` = ``sut_steps / wall_s``,
    ``steps_per_run`` (None when the runs differ)."""
    each = sorted(set(steps))
    return {"wall_s": wall_s, "startup_s": setup_s + ray_s + first_task_s, "setup_s": setup_s, "ray_s": ray_s,
            "first_task_s": first_task_s, "runs": runs, "sut_steps": sut_steps,
            "steps_per_run": each[0] if len(each) == 1 else None,
            "sut_steps_per_s": sut_steps / wall_s if wall_s > 0 else 0.0}


def _s(x: float) -> str:
    return f"{x:.1f} s" if x < 10 else f"{x:,.0f} s"


def line(d: Mapping[str, Any]) -> str:
    """One line of :func:`summary`'s figures (the module docstring's example)."""
    head = (f"wall {_s(d['wall_s'])}: start-up {_s(d['startup_s'])} (set-up {_s(d['setup_s'])}, Ray {_s(d['ray_s'])}, "
            f"workers' first task {_s(d['first_task_s'])})")
    if not d["runs"]:
        return f"{head}, no run computed"
    runs = (f"{d['runs']:,} runs × {d['steps_per_run']:,} SUT steps" if d["steps_per_run"] is not None
            else f"{d['runs']:,} runs, {d['sut_steps']:,} SUT steps")
    return f"{head}, {runs} = {d['sut_steps_per_s']:,.0f} SUT-steps/s"


def finish(out_dir: Path, file: TextIO | None = None) -> str:
    """The command's line printed (stdout) and its figures written to ``out_dir/timing.json``; returns the line."""
    d = COMMAND.summary()
    text = line(d)
    try:
        (out_dir / "timing.json").write_text(json.dumps({**d, "line": text}, indent=1) + "\n", encoding="utf-8")
    except OSError:  # a figure of speed: never a reason to fail the experiment
        pass
    print(text, file=file, flush=True)
    return text


def first_task_overheads(runs: Iterable[Mapping[str, Any]]) -> dict[str, float]:
    """Per worker, the overhead of its first task (seconds): ``runs`` are the computed runs' worker notes
    (``worker``, ``first``: the worker's first run, ``wait_s``: its task's submission to its start,
    ``wall_s``, ``steps``, ``built``: it built its start rather than copying it). The first run's time above
    ``steps`` × the median seconds per step of the other runs of its kind (built or copied; of any kind if none)."""
    runs = list(runs)
    per_step = {kind: [r["wall_s"] / r["steps"] for r in runs if not r["first"] and r["built"] == kind and r["steps"]]
                for kind in (True, False)}
    anyone = per_step[True] + per_step[False]
    out = {}
    for r in runs:
        if r["first"]:
            ref = per_step[r["built"]] or anyone
            extra = r["wall_s"] - r["steps"] * statistics.median(ref) if ref else 0.0
            out[r["worker"]] = max(0.0, r["wait_s"]) + max(0.0, extra)
    return out
