"""Campaigns: many runs from one YAML spec on Ray, each computed once (docs/campaigns.md).

A **spec** names a scenario configuration, the seeds, overrides for every run (``set``) and a
``grid`` of axes (scenario keys such as ``sut.model`` or ``bvs.driver``, and ``mutant``: a
mutant of the run's ``sut.model``, :mod:`evoscen_sut.mutants`, or ``intact``); the campaign is
every combination of the axes' values (a *cell*) for every seed. Each run is one Ray task of
one CPU that simulates and scores the run in-process (:func:`evoscen_bringup.inprocess.run_inprocess`).

**Once.** A run is keyed by a hash of its whole resolved configuration, of the code
version (:func:`code_version`: the content of evoscen's packages, maps and shipped policies) and,
for a run that uses a plug-in model, of that plug-in (:func:`plugin_versions`: its distribution's
name and version and the content of its module's files).
Its result (``OUT/runs/<key>/result.json`` with its ``report.json`` beside) is written by the
driver, atomically, when the task returns; a run whose result exists is never run again, so
an interrupted campaign resumes where it stopped, and the results table
(``OUT/results.parquet``, one row per run of the spec) is rebuilt from those files: no run
is counted twice. A task whose worker process dies is retried by Ray (``--retries``); a run
that still fails is reported and left without a result (the next invocation tries it again).

By default Ray is started in this process (a local cluster with one worker per CPU);
``address`` joins a running cluster (``ray start --head`` on one machine, ``ray start
--address`` on the others, with evoscen installed and sourced alike on every node).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import itertools
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from evoscen_eval.streaming import COLLISION_KINDS
from evoscen_sim.config import ScenarioConfig, config_to_dict, load_scenario_config
from evoscen_sim.errors import InputError

from .ray_leftovers import DRIVER_FILE, end_leftovers, start_time

SPEC_KEYS = ("name", "config", "steps", "seeds", "set", "grid", "record", "clip_s", "compare")
RECORD_MODES = ("none", "events", "all")
MUTANT_AXIS = "mutant"
INTACT = "intact"
PACKAGES = ("evoscen_contract", "evoscen_sim", "evoscen_bv", "evoscen_sut", "evoscen_record", "evoscen_eval",
            "evoscen_bringup")
SCORE_COLUMNS = ("intelligence", "safety", "efficiency", "interaction", "complexity")
COUNT_COLUMNS = ("collisions", "exposures")
KIND_COLUMNS = tuple(f"collisions_{k}" for k in (*COLLISION_KINDS, "unknown"))
"""SUT collisions by what they were (docs/evaluation.md §3.4)."""
TRAFFIC_COLUMNS = {"traffic_mean_bvs": "mean_bvs", "traffic_min_window_mean_bvs": "min_window_mean_bvs",
                   "traffic_empty_share": "empty_share"}
"""The traffic around the SUT (report.json's ``traffic``, docs/evaluation.md §8): column -> key."""
OBJECT_STORE_BYTES = 100 * 2**20
"""The local Ray's object store: tasks pass a configuration and return a report (kilobytes), so
100 MiB is plenty, and it fits a container's /dev/shm (ours: 256 MiB) instead of Ray's 30 % of RAM."""


@dataclass(frozen=True)
class Spec:
    """A campaign spec, validated (see the module docstring)."""

    path: Path
    name: str
    config: str | None
    steps: int | None
    seeds: tuple[int, ...]
    fixed: dict[str, str]
    grid: dict[str, tuple[str, ...]]
    record: str = "none"
    compare: tuple[str, str] | None = None
    clip_s: float = 5.0


@dataclass(frozen=True)
class CampaignRun:
    """One run of a campaign: its cell (axis → value), seed, configuration and key."""

    key: str
    cell: tuple[tuple[str, str], ...]
    seed: int
    cfg: ScenarioConfig


@dataclass
class CampaignResult:
    """What :func:`run_campaign` did."""

    runs: int
    already_done: int
    computed: int = 0
    failed: list[str] = field(default_factory=list)
    interrupted: bool = False
    wall_s: float = 0.0
    nodes: set[str] = field(default_factory=set)
    host_fault: str | None = None
    """Why the campaign stopped for a fault of the host (a full disk, an unwritable output): one
    line naming the file and the run; the run was not marked done, the same command resumes."""


# ---------------------------------------------------------------------- the spec


def _err(path: Path, key: str, value: Any, expected: str) -> InputError:
    return InputError(f"{path}: key {key!r} = {value!r}: expected {expected}")


def load_spec(path: Path | str) -> Spec:
    """Read and validate a campaign spec; InputError (one line naming the file and key) if it is wrong."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"campaign spec {str(path)!r}: cannot read: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"campaign spec {str(path)!r}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise InputError(f"campaign spec {str(path)!r}: expected a mapping of {', '.join(SPEC_KEYS)}")
    unknown = [k for k in doc if k not in SPEC_KEYS]
    if unknown:
        raise _err(path, str(unknown[0]), doc[unknown[0]], f"one of the keys {', '.join(SPEC_KEYS)}")
    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name.strip() or "/" in name:
        raise _err(path, "name", name, "a non-empty name without '/'")
    config = doc.get("config")
    if config is not None and not isinstance(config, str):
        raise _err(path, "config", config, "a scenario YAML file (relative to the spec) or null")
    if config is not None and not Path(config).is_absolute():
        config = str((path.parent / config).resolve())
    steps = doc.get("steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise _err(path, "steps", steps, "an integer >= 1")
    seeds = _seeds(path, doc.get("seeds", {"first": 0, "count": 1}))
    fixed = doc.get("set") or {}
    if not isinstance(fixed, dict):
        raise _err(path, "set", fixed, "a mapping of scenario keys to values")
    grid = doc.get("grid") or {}
    if not isinstance(grid, dict):
        raise _err(path, "grid", grid, "a mapping of axes (scenario keys or 'mutant') to lists of values")
    axes: dict[str, tuple[str, ...]] = {}
    for axis, values in grid.items():
        if not isinstance(values, list) or not values or len({str(v) for v in values}) != len(values):
            raise _err(path, f"grid.{axis}", values, "a non-empty list of distinct values")
        axes[str(axis)] = tuple(_text(v) for v in values)
    if MUTANT_AXIS in axes:
        from evoscen_sut.mutants import LIBRARY

        bad = [m for m in axes[MUTANT_AXIS] if m != INTACT and m not in LIBRARY]
        if bad:
            raise _err(path, f"grid.{MUTANT_AXIS}", bad[0], f"'{INTACT}' or a mutant of {', '.join(LIBRARY)}")
    record = doc.get("record", "none")
    if record not in RECORD_MODES:
        raise _err(path, "record", record, "'none' (scores only), 'events' (critical-event clips) or 'all' "
                   "(clips and the whole bag)")
    clip_s = doc.get("clip_s", 5.0)
    if isinstance(clip_s, bool) or not isinstance(clip_s, (int, float)) or not 0 < clip_s <= 60:
        raise _err(path, "clip_s", clip_s, "seconds in (0, 60] on either side of an event")
    compare = doc.get("compare")
    if compare is not None:
        if (not isinstance(compare, dict) or set(compare) != {"axis", "reference"}
                or compare["axis"] not in axes or _text(compare["reference"]) not in axes[compare["axis"]]):
            raise _err(path, "compare", compare, "{axis: <a grid axis>, reference: <one of its values>}")
        compare = (str(compare["axis"]), _text(compare["reference"]))
    return Spec(path, name.strip(), config, steps, seeds, {str(k): _text(v) for k, v in fixed.items()}, axes,
                record, compare, float(clip_s))


def _text(value: Any) -> str:
    """A spec value as the command-line override text of the scenario loader."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _seeds(path: Path, value: Any) -> tuple[int, ...]:
    if isinstance(value, list) and value and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                                                 for s in value) and len(set(value)) == len(value):
        return tuple(value)
    if isinstance(value, dict) and set(value) <= {"first", "count"} and "count" in value:
        first, count = value.get("first", 0), value["count"]
        if all(isinstance(x, int) and not isinstance(x, bool) for x in (first, count)) and first >= 0 and count >= 1:
            return tuple(range(first, first + count))
    raise _err(path, "seeds", value, "a list of distinct integers >= 0, or {first: N, count: M}")


def expand(spec: Spec, version: str | None = None) -> list[CampaignRun]:
    """Every run of the spec: each cell (combination of the axes' values, in the spec's order) × each seed."""
    version = code_version() if version is None else version
    axes = list(spec.grid)
    runs = []
    for values in itertools.product(*(spec.grid[a] for a in axes)) if axes else [()]:
        cell = tuple(zip(axes, values))
        overrides = dict(spec.fixed)
        mutant = None
        for axis, value in cell:
            if axis == MUTANT_AXIS:
                mutant = value
            else:
                overrides[axis] = value
        overrides["recording.enabled"] = "false" if spec.record == "none" else "true"
        if spec.steps is not None:
            overrides["steps"] = str(spec.steps)
        for seed in spec.seeds:
            over = {**overrides, "seed": str(seed)}
            try:
                cfg = load_scenario_config(spec.config, over)
                if mutant is not None and mutant != INTACT:
                    from evoscen_sut.mutants import mutant_overrides

                    cfg = load_scenario_config(spec.config, {**over, **mutant_overrides(cfg.sut.model, mutant)})
            except InputError as exc:
                raise InputError(f"{spec.path}: cell {dict(cell)}: {exc}") from None
            runs.append(CampaignRun(run_key(cfg, version), cell, seed, cfg))
    return runs


def run_key(cfg: ScenarioConfig, version: str) -> str:
    """The run's key: SHA-256 of its whole resolved configuration, the code version and the plug-ins
    the run uses (:func:`plugin_versions`; a run without one keeps the key it had before plug-ins
    were part of it) — 20 hex digits."""
    d = config_to_dict(cfg)
    text = json.dumps(d, sort_keys=True, default=str)
    plugins = plugin_versions(d)
    head = f"{version}\n{plugins}" if plugins else version
    return hashlib.sha256(f"{head}\n{text}".encode()).hexdigest()[:20]


def plugin_versions(config: dict[str, Any]) -> str:
    """The plug-in models a resolved configuration (:func:`config_to_dict`) names — any of its values
    or ``models`` keys that is a plug-in's model name: ``sut.model``, ``bvs.driver``, a mutant's
    ``models.mutant.base`` — each as ``name=distribution==version:hash`` (:func:`plugin_fingerprint`),
    sorted and joined by ``;``; empty when it names none."""
    from evoscen_sim.models import plugin_entry_point

    names: set[str] = set()

    def walk(value: Any) -> None:
        if isinstance(value, str):
            names.add(value)
        elif isinstance(value, dict):
            for v in value.values():
                walk(v)
        elif isinstance(value, (list, tuple)):
            for v in value:
                walk(v)

    walk(config)
    names.update(str(k) for k in (config.get("models") or {}))
    parts = []
    for name in sorted(names):
        ep = plugin_entry_point(name)
        if ep is not None:
            dist = ep.dist
            parts.append(f"{name}={plugin_fingerprint(ep.module, dist.name if dist else '?', dist.version if dist else '?')}")
    return ";".join(parts)


@functools.lru_cache(maxsize=None)
def plugin_fingerprint(module: str, dist_name: str, dist_version: str) -> str:
    """``distribution==version:hash``: the hash (16 hex digits) covers the files of the plug-in's
    top-level module — every file of its package directory (``__pycache__`` left out), or the one
    ``.py`` file of a single-module plug-in — so an edited plug-in (an editable install, a changed
    file in place) gets new keys even when its version stays. Cached per process, like
    :func:`code_version`."""
    import importlib.util

    top = module.split(".")[0]
    spec = importlib.util.find_spec(top)
    files: list[tuple[str, Path]] = []
    if spec is not None and spec.submodule_search_locations:
        root = Path(next(iter(spec.submodule_search_locations))).resolve()
        files = [(f.relative_to(root).as_posix(), f) for f in sorted(root.rglob("*"))
                 if f.is_file() and "__pycache__" not in f.parts]
    elif spec is not None and spec.origin and Path(spec.origin).is_file():
        files = [(Path(spec.origin).name, Path(spec.origin))]
    h = hashlib.sha256()
    for rel, f in files:
        h.update(rel.encode())
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return f"{dist_name}=={dist_version}:{h.hexdigest()[:16]}"


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """A hash of what decides a run's result besides its configuration: the files of evoscen's
    packages (sources, maps, configuration) and the shipped BV policies."""
    from evoscen_bv.learned import shipped_policy_dir

    roots = [Path(importlib.import_module(p).__file__).resolve().parent for p in PACKAGES]
    from evoscen_sim.share import share_candidates

    roots += [c for c in share_candidates("maps") if c.is_dir()][:1]
    policies = shipped_policy_dir()
    if policies.is_dir():
        roots.append(policies.resolve())
    h = hashlib.sha256()
    for root in roots:
        for f in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
            h.update(f.relative_to(root).as_posix().encode())
            h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:16]


# ---------------------------------------------------------------------- one run (a Ray task)


def execute(run: CampaignRun, out_dir: str, record: str, clip_s: float = 5.0) -> dict[str, Any]:
    """Simulate and score one run (in the worker); returns its result row, report, plot data and,
    when recording, its files (``{path relative to the run's directory: bytes}``: the critical-event
    clips, and the whole bag with ``record: all``), which the driver writes — on a cluster the
    worker's disk is not the driver's."""
    import tempfile

    from evoscen_sim.errors import HostFault

    t0 = time.perf_counter()
    try:
        summary, files, clips = _simulate(run, out_dir, record, clip_s)
    except OSError as exc:  # the worker's temporary directory (the bag, the clips): a fault of the host
        raise HostFault.of(exc, exc.filename or tempfile.gettempdir()) from None
    report = summary.report
    row: dict[str, Any] = {"key": run.key, **dict(run.cell), "seed": run.seed, "steps": summary.steps}
    for name in SCORE_COLUMNS:
        value = report[name]["score"]
        row[name] = math.nan if value is None else float(value)
    row["collisions"] = int(report["safety"]["collisions"])
    for kind, count in report["safety"]["collisions_by_kind"].items():
        row[f"collisions_{kind}"] = int(count)
    row["exposures"] = int(report["safety"]["exposures"])
    row.update(traffic_columns(report))
    row["clips"] = len(clips)
    row["wall_time_s"] = time.perf_counter() - t0
    try:
        import ray

        row["node"] = ray.get_runtime_context().get_node_id()[:12]
    except Exception:  # noqa: BLE001 - outside Ray (tests call it directly)
        row["node"] = "local"
    row["pid"] = os.getpid()
    plot = {"ttc_hist": summary.plot.ttc_hist.tolist(), "speed_hist": summary.plot.speed_hist.tolist()}
    return {"row": row, "report": report, "plot": plot, "files": files}


def _simulate(run: CampaignRun, out_dir: str, record: str, clip_s: float):
    """The run's summary, files and clips (:func:`execute`), recorded in a temporary directory."""
    import tempfile

    from evoscen_eval.clips import mine_run

    from .inprocess import run_inprocess

    files: dict[str, bytes] = {}
    clips: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="evoscen-run-") as tmp:
        bag = Path(tmp) / "bag" if record != "none" else None
        # inline: a campaign runs one task per CPU, so there is no free core for a writer process
        summary = run_inprocess(run.cfg, bag_dir=bag, evaluate=True, plots=False, bag_writer="inline")
        if bag is not None:
            scenario_file = (Path(out_dir) / "runs" / run.key / "scenario.yaml").resolve()
            clips = mine_run(bag, summary.report, Path(tmp), clip_s=clip_s, scenario_file=scenario_file,
                             run_name=run.key)
            for f in sorted(Path(tmp).rglob("*")):
                rel = f.relative_to(tmp)
                if f.is_file() and (record == "all" or rel.parts[0] != "bag"):
                    files[rel.as_posix()] = f.read_bytes()
    return summary, files, clips


def traffic_columns(report: Mapping[str, Any]) -> dict[str, float]:
    """A run's :data:`TRAFFIC_COLUMNS` from its report (NaN where undefined: no traffic window)."""
    traffic = report.get("traffic") or {}
    return {column: math.nan if traffic.get(key) is None else float(traffic[key])
            for column, key in TRAFFIC_COLUMNS.items()}


# ---------------------------------------------------------------------- the campaign


def result_path(out_dir: Path, key: str) -> Path:
    return out_dir / "runs" / key / "result.json"


def _write_atomic(path: Path, text: str) -> None:
    """``path`` with ``text``, whole or not at all (a temporary file renamed; removed on failure)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _host_fault_of(exc: BaseException):  # HostFault | None
    """The :class:`~evoscen_sim.errors.HostFault` behind a task's error (Ray wraps it), or None."""
    from evoscen_sim.errors import HostFault

    for _ in range(8):
        if exc is None:
            return None
        inner = getattr(exc, "cause", None)  # Ray's RayTaskError: the task's own exception
        if isinstance(inner, BaseException):  # (the wrapper is a HostFault too, without its fields)
            exc = inner
        elif isinstance(exc, HostFault):
            return exc
        else:
            exc = exc.__cause__
    return None


def _task_error(exc: BaseException) -> str:
    """One line for a failed task: the task's own exception (Ray wraps it), its type and first line."""
    for _ in range(8):
        inner = getattr(exc, "cause", None)  # Ray's RayTaskError: the task's own exception
        if not isinstance(inner, BaseException) or inner is exc:
            break
        exc = inner
    text = str(exc)
    return f"{type(exc).__name__}: {text.splitlines()[0] if text else ''}"


def _write_files(run_dir: Path, files: Mapping[str, bytes]) -> None:
    """A run's files from its worker (clips, bag), replacing any of an earlier, interrupted attempt."""
    import shutil

    for top in {Path(rel).parts[0] for rel in files}:
        if (run_dir / top).is_dir():
            shutil.rmtree(run_dir / top)
    for rel, data in files.items():
        target = run_dir / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)


def run_campaign(runs: Sequence[CampaignRun], out_dir: Path, *, record: str = "none", clip_s: float = 5.0,
                 address: str | None = None, cpus: int | None = None, retries: int = 3,
                 progress: Callable[[int, int, float], None] | None = None) -> CampaignResult:
    """Run every run of ``runs`` without a result in ``out_dir`` on Ray (see the module docstring).

    ``progress(done, total, runs_per_s)`` after each finished run. Ctrl-C cancels what is left
    (finished runs are kept; ``interrupted`` is set). :func:`write_results` writes the table.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    end_leftovers(out_dir)  # of a driver that was killed (scripts/campaign.py names them)
    todo = [r for r in runs if not result_path(out_dir, r.key).exists()]
    result = CampaignResult(runs=len(runs), already_done=len(runs) - len(todo))
    t0 = time.monotonic()
    if todo:
        with _ctrl_c_interrupts() as arm:
            _run_todo(todo, out_dir, result, len(runs), t0, record=record, clip_s=clip_s, address=address,
                      cpus=cpus, retries=retries, progress=progress, arm=arm)
    result.wall_s = time.monotonic() - t0
    return result


@contextlib.contextmanager
def _ctrl_c_interrupts():
    """Yields ``arm()``: from then on Ctrl-C (SIGINT) and SIGTERM raise KeyboardInterrupt in this
    (main) thread, whatever the process inherited — a background job of a non-interactive shell
    starts with SIGINT ignored, and Python then installs no handler (CI's test run once ignored
    the test's Ctrl-C). Called after ``ray.init``, which may set handlers of its own; the old
    handlers are restored at the end."""
    import signal
    import threading

    saved: dict[int, Any] = {}

    def arm() -> None:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                saved.setdefault(sig, signal.getsignal(sig))
                signal.signal(sig, signal.default_int_handler)

    try:
        yield arm
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def _run_todo(todo: Sequence[CampaignRun], out_dir: Path, result: CampaignResult, total: int, t0: float, *,
              record: str, clip_s: float, address: str | None, cpus: int | None, retries: int,
              progress: Callable[[int, int, float], None] | None, arm: Callable[[], None]) -> None:
    """Submit ``todo`` to Ray and write each result as it comes (see :func:`run_campaign`)."""
    import ray

    started = not ray.is_initialized()
    if started:
        local = {} if address else {"num_cpus": cpus, "object_store_memory": OBJECT_STORE_BYTES}
        ctx = ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False,
                       **local)
        if not address:  # this driver's own Ray: noted, so that the next driver can end what a kill leaves
            session = (getattr(ctx, "address_info", None) or {}).get("session_dir")
            if session:
                _note_driver(out_dir, session)
    arm()
    task = ray.remote(num_cpus=1, max_retries=retries, retry_exceptions=False)(execute)
    pending = {task.remote(r, str(out_dir), record, clip_s): r for r in todo}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
            for ref in ready:
                run = pending.pop(ref)
                try:
                    done = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - the task failed after its retries
                    fault = _host_fault_of(exc)
                    if fault is not None:  # the worker's disk: every other run would fail alike
                        result.host_fault = (f"run {run.key} (seed {run.seed}): cannot write {fault.path} on its "
                                             f"worker: {fault.cause}")
                        raise _HostFaultStop from None
                    result.failed.append(f"{run.key} ({dict(run.cell)}, seed {run.seed}): {_task_error(exc)}")
                    continue
                path = result_path(out_dir, run.key)
                try:
                    _write_files(path.parent, done["files"])
                    _write_atomic(path.with_name("scenario.yaml"),
                                  yaml.safe_dump(config_to_dict(run.cfg), sort_keys=False))
                    _write_atomic(path.with_name("report.json"), json.dumps(done["report"], indent=1) + "\n")
                    _write_atomic(path.with_name("plot.json"), json.dumps(done["plot"]) + "\n")
                    _write_atomic(path, json.dumps(done["row"]) + "\n")  # last: the run counts as done
                except OSError as exc:  # not marked done: the same command computes it again
                    from evoscen_sim.errors import HostFault

                    fault = HostFault.of(exc, exc.filename or path.parent)
                    result.host_fault = f"run {run.key} (seed {run.seed}): {fault}"
                    raise _HostFaultStop from None
                result.computed += 1
                result.nodes.add(done["row"]["node"])
                if progress is not None:
                    rate = result.computed / max(time.monotonic() - t0, 1e-9)
                    progress(result.already_done + result.computed, total, rate)
    except (KeyboardInterrupt, _HostFaultStop) as exc:
        result.interrupted = isinstance(exc, KeyboardInterrupt)
        if not started:  # a cluster's workers outlive this driver: ask them to drop our tasks
            for ref in pending:
                with contextlib.suppress(Exception):
                    ray.cancel(ref)
        # (a local Ray goes down with its workers below; a forced cancel racing a task that
        # is just completing aborted the driver inside Ray, seen once on this machine)
    finally:
        if started:
            ray.shutdown()
            with contextlib.suppress(OSError):
                (out_dir / DRIVER_FILE).unlink()


def _note_driver(out_dir: Path, session_dir: str) -> None:
    with contextlib.suppress(OSError):  # only a help for the next start: never a reason to stop
        _write_atomic(out_dir / DRIVER_FILE, json.dumps({"pid": os.getpid(), "start": start_time(os.getpid()),
                                                          "session_dir": session_dir}) + "\n")


class _HostFaultStop(Exception):
    """Stops the campaign's loop after a fault of the host (``CampaignResult.host_fault`` says which)."""


def load_result(out_dir: Path, key: str) -> dict[str, Any]:
    """A finished run's files: ``{"row", "report", "plot"}`` (``plot``: the SUT's TTC and speed
    histograms over :data:`evoscen_eval.streaming.TTC_BINS` and ``SPEED_BINS``)."""
    d = out_dir / "runs" / key
    return {name: json.loads((d / f"{name if name != 'row' else 'result'}.json").read_text(encoding="utf-8"))
            for name in ("row", "report", "plot")}


def collect_rows(runs: Sequence[CampaignRun], out_dir: Path) -> list[dict[str, Any]]:
    """The result rows of ``runs`` that have one, in the spec's order (each run at most once)."""
    rows = []
    for r in runs:
        path = result_path(out_dir, r.key)
        if path.exists():
            rows.append(json.loads(path.read_text(encoding="utf-8")))
    return rows


def write_results(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> list[dict[str, Any]]:
    """``results.parquet`` (one row per finished run of the spec) and ``summary.md``, each written
    whole or not at all (a temporary file renamed). An output that cannot be written is a
    :class:`~evoscen_sim.errors.HostFault` naming the file (the runs' results are kept)."""
    from evoscen_sim.errors import HostFault

    try:
        return _write_results(spec, runs, out_dir)
    except OSError as exc:
        with contextlib.suppress(OSError):
            (out_dir / "results.parquet.tmp").unlink()
        raise HostFault.of(exc, exc.filename or out_dir) from None


def _write_results(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> list[dict[str, Any]]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows = collect_rows(runs, out_dir)
    axes = list(spec.grid)
    columns = ["key", *axes, "seed", "steps", *SCORE_COLUMNS, *COUNT_COLUMNS, *KIND_COLUMNS, *TRAFFIC_COLUMNS, "clips",
               "wall_time_s",
               "node", "pid"]
    table = pa.table({c: [row.get(c) for row in rows] for c in columns}) if rows else pa.table(
        {c: pa.array([], type=pa.string()) for c in columns})
    tmp = out_dir / "results.parquet.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, out_dir / "results.parquet")
    images = summary_plots(spec, runs, rows, out_dir) if rows else []
    _write_atomic(out_dir / "summary.md", summary_markdown(spec, runs, rows)
                  + "".join(f"\n![{Path(name).stem}]({name})\n" for name in images))
    if spec.record != "none":
        _write_atomic(out_dir / "gallery.md", gallery_markdown(spec, runs, out_dir))
    return rows


def summary_plots(spec: Spec, runs: Sequence[CampaignRun], rows: Sequence[Mapping[str, Any]],
                  out_dir: Path) -> list[str]:
    """``summary.png`` (per cell: mean I with its 95 % interval) and ``distributions.png`` (per cell:
    the SUT's TTC and speed distributions over all its runs, as fractions of states)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from evoscen_eval.streaming import SPEED_BINS, TTC_BINS

    from .stats import mean_ci

    grouped = cells(spec, rows)
    labels = [", ".join(cell) or spec.name for cell in grouped]
    stats = [mean_ci([m["intelligence"] for m in members if not math.isnan(m["intelligence"])])
             for members in grouped.values()]
    fig, ax = plt.subplots(figsize=(max(6.0, 0.6 * len(labels) + 2), 4))
    x = np.arange(len(labels))
    ax.bar(x, [m for m, _ in stats], yerr=[0.0 if math.isnan(h) else h for _, h in stats], capsize=3,
           color="tab:blue")
    ax.set_xticks(x, labels, rotation=45, ha="right", fontsize=8)
    ax.set(ylabel="intelligence I (mean, 95 % interval)", title=f"campaign {spec.name}: {len(rows)} runs")
    fig.tight_layout()
    fig.savefig(out_dir / "summary.png", dpi=100)
    plt.close(fig)
    key_of = {r.key: ", ".join(v for _, v in r.cell) or spec.name for r in runs}
    hists: dict[str, list[np.ndarray]] = {}
    for row in rows:
        path = out_dir / "runs" / row["key"] / "plot.json"
        if path.exists():
            plot = json.loads(path.read_text(encoding="utf-8"))
            h = hists.setdefault(key_of[row["key"]], [np.zeros(len(TTC_BINS) - 1), np.zeros(len(SPEED_BINS) - 1)])
            h[0] += plot["ttc_hist"]
            h[1] += plot["speed_hist"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for label, (ttc, speed) in hists.items():
        for ax, h, bins in ((axes[0], ttc, TTC_BINS), (axes[1], speed, SPEED_BINS)):
            if h.sum():
                ax.stairs(h / h.sum(), bins, label=label)
    axes[0].set(xlabel="SUT TTC to the vehicle ahead (s, closing states up to 20 s)", ylabel="fraction")
    axes[1].set(xlabel="SUT speed (m/s)", ylabel="fraction")
    if len(hists) <= 12:
        axes[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / "distributions.png", dpi=100)
    plt.close(fig)
    return ["summary.png", "distributions.png"]


def gallery_markdown(spec: Spec, runs: Sequence[CampaignRun], out_dir: Path) -> str:
    """``gallery.md``: every critical event of the finished runs, most severe first
    (:func:`evoscen_eval.clips.rank_key`), with its picture, clip and reproduce command."""
    from evoscen_eval.clips import rank_key

    events = []
    for r in runs:
        path = out_dir / "runs" / r.key / "clips.json"
        if result_path(out_dir, r.key).exists() and path.exists():
            events += [(e, r) for e in json.loads(path.read_text(encoding="utf-8"))]
    events.sort(key=lambda item: rank_key(item[0]))
    lines = [f"# Critical events of campaign {spec.name}\n",
             f"{len(events)} events (SUT collisions, then exposures by severity max(2 s / TTC, −a / 6 m/s²)); "
             f"each a clip of ±{spec.clip_s:g} s (`python scripts/replay.py CLIP`, Foxglove) and the command that "
             "runs the same configuration to the clip's end.\n",
             "| rank | event | cell | seed | t (s) | severity | min TTC (s) | scene | clip | reproduce |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for n, (e, r) in enumerate(events, 1):
        base = f"runs/{r.key}"
        pic = f"![scene]({base}/{e['png']})" if e.get("png") else "–"
        sev = "–" if e["severity"] is None else f"{e['severity']:.2f}"
        ttc = "–" if e.get("min_ttc_s") is None else f"{e['min_ttc_s']:.2f}"
        cell = ", ".join(f"{k}={v}" for k, v in r.cell) or "–"
        lines.append(f"| {n} | {e['kind']} | {cell} | {r.seed} | {e['time_s']:.1f} | {sev} | {ttc} | {pic} | "
                     f"`{base}/{e['clip']}` | `{e.get('command') or '–'}` |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- statistics


def bootstrap_ci(values: Sequence[float], rng: np.random.Generator, draws: int = 2000) -> tuple[float, float, float]:
    """Mean and its 95 % percentile-bootstrap interval ``(mean, low, high)`` (for skewed counts
    such as collisions); ``nan`` bounds with fewer than 2 values."""
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    if x.size < 2:
        return float(x.mean()), math.nan, math.nan
    means = x[rng.integers(0, x.size, size=(draws, x.size))].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5])
    return float(x.mean()), float(low), float(high)


def cells(spec: Spec, rows: Sequence[Mapping[str, Any]]) -> dict[tuple[str, ...], list[Mapping[str, Any]]]:
    """Rows grouped by cell (the axes' values in the spec's order)."""
    out: dict[tuple[str, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        out.setdefault(tuple(str(row[a]) for a in spec.grid), []).append(row)
    return out


def summary_markdown(spec: Spec, runs: Sequence[CampaignRun], rows: Sequence[Mapping[str, Any]]) -> str:
    """Per-cell means with 95 % intervals (Student t for scores, bootstrap for counts) and, with
    ``compare``, paired differences to the reference on shared seeds."""
    from .sensitivity import paired
    from .stats import fmt_ci, markdown_table, mean_ci

    axes = list(spec.grid)
    lines = [f"# Campaign {spec.name}\n",
             f"{len(rows)} of {len(runs)} runs finished; {len(spec.seeds)} seeds per cell; spec `{spec.path.name}`. "
             "Scores: mean ± 95 % Student-t interval over seeds (C: the scenario's complexity per run, – for a "
             "run shorter than one window); counts: mean [95 % bootstrap interval].\n"]
    rng = np.random.default_rng(0)  # the bootstrap's draws: fixed, so the summary is reproducible
    body = []
    grouped = cells(spec, rows)
    for cell, members in grouped.items():
        entry = [*cell, str(len(members))]
        for name in ("intelligence", "safety", "efficiency", "interaction", "complexity"):
            vals = [m[name] for m in members if m[name] is not None and not math.isnan(m[name])]
            entry.append(fmt_ci(*mean_ci(vals)) if vals else "–")
        for name in COUNT_COLUMNS:
            mean, low, high = bootstrap_ci([m[name] for m in members], rng)
            entry.append(f"{mean:.2f} [{low:.2f}, {high:.2f}]" if not math.isnan(low) else f"{mean:.2f}")
        kinds = {c[len("collisions_"):]: sum(m.get(c) or 0 for m in members) for c in KIND_COLUMNS}
        entry.append(", ".join(f"{k} {n}" for k, n in kinds.items() if n) or "–")
        body.append(entry)
    lines.append(markdown_table([*axes, "n", "I", "I_s", "I_e", "I_i", "C", "collisions", "exposures",
                                 "collisions by kind (all seeds)"], body))
    if spec.compare is not None and rows:
        axis, ref = spec.compare
        i = axes.index(axis)
        comp = []
        for cell, members in grouped.items():
            if cell[i] == ref:
                continue
            ref_cell = cell[:i] + (ref,) + cell[i + 1:]
            base = {m["seed"]: m["intelligence"] for m in grouped.get(ref_cell, [])}
            other = {m["seed"]: m["intelligence"] for m in members}
            p = paired(base, other)
            comp.append([*cell, str(p.n), fmt_ci(p.mean, p.half), "yes" if p.above_zero else "no"])
        lines.append(f"\n## Paired by seed: {ref} − each other {axis} (intelligence)\n")
        lines.append(markdown_table([*axes, "seeds", "ΔI", "interval above 0"], comp))
    return "\n".join(lines) + "\n"
