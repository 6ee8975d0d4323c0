"""Campaigns: many runs from one YAML spec on Ray, each computed once (docs/campaigns.md).

The spec, its runs and their keys are :mod:`evoscen_experiments.campaign_spec`; the results table,
summary and gallery :mod:`evoscen_experiments.campaign_summary`. Each run is one Ray task of one CPU
that simulates and scores the run in-process (:func:`evoscen_bringup.inprocess.run_inprocess`).

**Once.** A run's result (``OUT/runs/<key>/result.json`` with its ``report.json`` beside) is
written by the driver, atomically, when the task returns; a run whose result exists is never
run again, so an interrupted campaign resumes where it stopped, and the results table
(``OUT/results.parquet``, one row per run of the spec) is rebuilt from those files: no run
is counted twice. A task whose worker process dies is retried by Ray (``--retries``); a run
that still fails is reported and left without a result (the next invocation tries it again).

By default Ray is started in this process (a local cluster with one worker per CPU);
``address`` joins a running cluster (``ray start --head`` on one machine, ``ray start
--address`` on the others, with evoscen installed and sourced alike on every node).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from evoscen_eval.scoring.sut_collisions import COLLISION_KINDS
from evoscen_sim.config.scenario_config import config_to_dict

from evoscen_experiments.campaign_spec import CampaignRun
from evoscen_experiments.ray_leftovers import DRIVER_FILE, end_leftovers, start_time

SCORE_COLUMNS = {"comparative": "D", "comparative_safety": "S", "comparative_progress": "P",
                 "comparative_lane_change_time": "L", "comparative_interaction": "X",
                 "intelligence": "I", "intelligence_safety": "I_s", "intelligence_efficiency": "I_e",
                 "intelligence_interaction": "I_i", "complexity": "K"}
"""A run's scores, column -> symbol (docs/evaluation.md, "Symbols"): D, the comparative score, and its terms;
the method's I and its terms (``intelligence`` is always the method's I); the scenario's complexity K."""
COUNT_COLUMNS = ("collisions", "exposures")
KIND_COLUMNS = tuple(f"collisions_{k}" for k in (*COLLISION_KINDS, "unknown"))
"""SUT collisions by what they were (docs/evaluation.md §3.4)."""
TRAFFIC_COLUMNS = {"traffic_mean_bvs": "mean_bvs", "traffic_min_window_mean_bvs": "min_window_mean_bvs",
                   "traffic_empty_share": "empty_share"}
"""The traffic around the SUT (report.json's ``traffic``, docs/evaluation.md §8): column -> key."""
OBJECT_STORE_BYTES = 100 * 2**20
"""The local Ray's object store: tasks pass a configuration and return a report (kilobytes), so
100 MiB is plenty, and it fits a container's /dev/shm (ours: 256 MiB) instead of Ray's 30 % of RAM."""


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
    ray_s: float = 0.0
    """``ray.init`` (0 when Ray was running already)."""
    first_task_s: float = 0.0
    """The workers' first-task overhead, mean over workers (:func:`evoscen_experiments.timing.first_task_overheads`)."""


# ---------------------------------------------------------------------- one run (a Ray task)


def score_columns(report: dict[str, Any]) -> dict[str, float | None]:
    """A report's :data:`SCORE_COLUMNS` (None where a score is undefined or the report has no D)."""
    d = report.get("comparative") or {}
    term = lambda k: (d.get(k) or {}).get("score")  # noqa: E731
    return {"comparative": d.get("score"), "comparative_safety": term("safety"), "comparative_progress": term("progress"),
            "comparative_lane_change_time": term("lane_change_time"), "comparative_interaction": term("interaction"),
            "intelligence": report["intelligence"]["score"], "intelligence_safety": report["safety"]["score"],
            "intelligence_efficiency": report["efficiency"]["score"],
            "intelligence_interaction": report["interaction"]["score"], "complexity": report["complexity"]["score"]}


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
    return _answer(run, summary, files, clips, time.perf_counter() - t0)


def _answer(run: CampaignRun, summary, files: dict[str, bytes], clips: list, wall_s: float) -> dict[str, Any]:
    """:func:`execute`'s answer for a run simulated and scored (``summary``), its time ``wall_s``."""
    report = summary.report
    row: dict[str, Any] = {"key": run.key, **dict(run.cell), "seed": run.seed, "steps": summary.steps}
    for name, value in score_columns(report).items():
        row[name] = math.nan if value is None else float(value)
    row["score_form"] = (report.get("settings") or {}).get("score_form", "method")  # the score a summary compares
    row["collisions"] = int(report["safety"]["collisions"])
    for kind, count in report["safety"]["collisions_by_kind"].items():
        row[f"collisions_{kind}"] = int(count)
    row["exposures"] = int(report["safety"]["exposures"])
    row.update(traffic_columns(report))
    row["clips"] = len(clips)
    row["wall_time_s"] = wall_s
    row["node"] = "local"
    try:
        import ray

        if ray.is_initialized():  # else outside Ray (tests, the benchmark): asking would start a Ray
            row["node"] = ray.get_runtime_context().get_node_id()[:12]
    except Exception:  # noqa: BLE001 - outside Ray
        pass
    row["pid"] = os.getpid()
    plot = {"ttc_hist": summary.plot.ttc_hist.tolist(), "speed_hist": summary.plot.speed_hist.tolist()}
    return {"row": row, "report": report, "plot": plot, "files": files}


def execute_batch(runs: Sequence[CampaignRun], out_dir: str, record: str,
                  clip_s: float = 5.0, sent: float | None = None, lockstep: bool = False) -> list[dict[str, Any]]:
    """:func:`execute` for each run of a batch (one Ray task), in order; a run that fails gives
    ``{"error": one line, "host_fault": (path, cause) or None}`` in its place and the others go on.
    The runs of a batch share their start when they can (:mod:`evoscen_bringup.starts`). A run's answer
    notes for the start-up figures (:mod:`evoscen_experiments.timing`) whether it was this worker's first,
    the task's wait since ``sent`` (its submission, :func:`time.time`) and whether it built its start.
    ``lockstep`` (runs without a bag): the batch's runs step together (:func:`_execute_lockstep`), the same answers."""
    global _RUNS_DONE
    wait_s = 0.0 if sent is None else time.time() - sent
    if lockstep and record == "none" and len(runs) > 1:
        return _execute_lockstep(runs, wait_s)
    out = []
    for run in runs:
        built = 0 if _STARTS is None else _STARTS.built
        try:
            done = execute(run, out_dir, record, clip_s)
            built_now = _STARTS is not None and _STARTS.built > built  # no start cache: the run built none
            done["worker"] = {"first": _RUNS_DONE == 0, "wait_s": wait_s, "built": built_now}
            out.append(done)
        except Exception as exc:  # noqa: BLE001 - reported per run by the driver, as a failed task is
            out.append(_failure(exc))
        _RUNS_DONE += 1
    return out


def _execute_lockstep(runs: Sequence[CampaignRun], wait_s: float) -> list[dict[str, Any]]:
    """:func:`execute_batch` of runs without a bag, stepped in lockstep in this process
    (:func:`evoscen_bringup.inprocess.run_plans`): each run's answer is :func:`execute`'s (the same row, report and
    plot data), its ``wall_time_s`` its own set-up (its start built or copied) plus its share of the stepping."""
    global _RUNS_DONE
    from evoscen_bringup.inprocess import run_plans
    from evoscen_bringup.plan import plan_of

    answers: list[dict[str, Any] | None] = [None] * len(runs)
    plans, where, setup, built = [], [], [], []
    for j, run in enumerate(runs):
        before = _starts().built
        t0 = time.perf_counter()
        try:  # a shared start (the warm-up once per start); one driver of all BVs, as _simulate without a bag
            plans.append(plan_of(run.cfg, recorded=False, scenario=_starts().scenario(run.cfg, partitioned=False)))
        except Exception as exc:  # noqa: BLE001 - this run's failure; the others go on
            answers[j] = _failure(exc)
            continue
        where.append(j)
        setup.append(time.perf_counter() - t0)
        built.append(_starts().built > before)
    t0 = time.perf_counter()
    results = run_plans(plans)
    share = (time.perf_counter() - t0) / max(len(plans), 1)
    for j, res, own, new in zip(where, results, setup, built):
        if isinstance(res, Exception):
            answers[j] = _failure(res)
            continue
        done = _answer(runs[j], res, {}, [], own + share)
        done["worker"] = {"first": _RUNS_DONE + j == 0, "wait_s": wait_s, "built": new}
        answers[j] = done
    _RUNS_DONE += len(runs)  # every run given, failed or not, as one at a time counts them
    return answers  # type: ignore[return-value]


def _failure(exc: BaseException) -> dict[str, Any]:
    """A failed run's answer (:func:`execute_batch`): its error line and, for a fault of the host, the
    file and the reason (plain values: they travel back from the worker)."""
    fault = _host_fault_of(exc)
    return {"error": _task_error(exc), "host_fault": None if fault is None else (str(fault.path), fault.cause)}


_STARTS = None  # this worker's StartCache (evoscen_bringup.starts), made on first use
_RUNS_DONE = 0  # runs this worker process was given (its first one carries the worker's once-only costs)


def _starts():
    global _STARTS
    if _STARTS is None:
        from evoscen_bringup.starts import StartCache

        _STARTS = StartCache()
    return _STARTS


def _simulate(run: CampaignRun, out_dir: str, record: str, clip_s: float):
    """The run's summary, files and clips (:func:`execute`), recorded in a temporary directory."""
    import tempfile

    from evoscen_eval.scenes.clips import mine_run

    from evoscen_bringup.inprocess import run_inprocess

    files: dict[str, bytes] = {}
    clips: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="evoscen-run-") as tmp:
        bag = Path(tmp) / "bag" if record != "none" else None
        # a shared start (the warm-up once per start); without a bag one driver of all BVs
        scenario = _starts().scenario(run.cfg, partitioned=bag is not None)
        # inline: a campaign runs one task per CPU, so there is no free core for a writer process
        summary = run_inprocess(run.cfg, bag_dir=bag, scenario=scenario, evaluate=True, plots=False,
                                bag_writer="inline")
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


def write_atomic(path: Path, text: str) -> None:
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


BATCH_RUNS = 16
"""The most runs one Ray task computes (:func:`batches`): a start's SUT variants go together so that the
warm-up is computed once for them; a cap keeps the tasks many enough to share out (docs/performance.md)."""
LOCKSTEP = False
"""[choice] An experiment's task steps its runs one after the other; True: in lockstep (:func:`_execute_lockstep`;
an experiment's ``--batch N``). The same results either way (tested); without kernels over many worlds, lockstep
costs ~12 % more per run (the worlds' data in turn through the caches: docs/performance.md "Many worlds at once")."""


def batches(runs: Sequence[CampaignRun], group: Callable[[CampaignRun], Any] | None,
            size: int = BATCH_RUNS) -> list[list[CampaignRun]]:
    """``runs`` cut into Ray tasks: with ``group``, the runs of one group value (in the order of their
    first run) in batches of at most ``size``; without, one run per task."""
    if group is None or size <= 1:
        return [[r] for r in runs]
    groups: dict[Any, list[CampaignRun]] = {}
    for r in runs:
        groups.setdefault(group(r), []).append(r)
    return [g[i:i + size] for g in groups.values() for i in range(0, len(g), size)]


def run_campaign(runs: Sequence[CampaignRun], out_dir: Path, *, record: str = "none", clip_s: float = 5.0,
                 address: str | None = None, cpus: int | None = None, retries: int = 3,
                 progress: Callable[[int, int, float, float], None] | None = None,
                 group: Callable[[CampaignRun], Any] | None = None, batch_runs: int = BATCH_RUNS,
                 lockstep: bool = False) -> CampaignResult:
    """Run every run of ``runs`` without a result in ``out_dir`` on Ray (see the module docstring).

    ``progress(done, total, runs_per_s, sut_steps_per_s)`` after each finished run, the rates over the
    command's wall so far (:data:`evoscen_experiments.timing.COMMAND`). Ctrl-C cancels what is left
    (finished runs are kept; ``interrupted`` is set). :func:`~evoscen_experiments.campaign_summary.write_results` writes the table.
    ``group`` (e.g. :func:`evoscen_bringup.starts.start_key` of the run's configuration): the runs of
    one value go to one task, up to ``batch_runs`` at a time (:func:`batches`); the results are the same.
    ``lockstep``: a task's runs without a bag step together in its worker (:func:`execute_batch`); the same results.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    end_leftovers(out_dir)  # of a driver that was killed (scripts/campaign.py names them)
    todo = [r for r in runs if not result_path(out_dir, r.key).exists()]
    result = CampaignResult(runs=len(runs), already_done=len(runs) - len(todo))
    t0 = time.monotonic()
    if todo:
        with _ctrl_c_interrupts() as arm:
            _run_todo(batches(todo, group, batch_runs), out_dir, result, len(runs), record=record,
                      clip_s=clip_s, address=address, cpus=cpus, retries=retries, progress=progress, arm=arm,
                      lockstep=lockstep)
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


def _run_todo(todo: Sequence[Sequence[CampaignRun]], out_dir: Path, result: CampaignResult, total: int, *,
              record: str, clip_s: float, address: str | None, cpus: int | None, retries: int,
              progress: Callable[[int, int, float, float], None] | None, arm: Callable[[], None],
              lockstep: bool = False) -> None:
    """Submit ``todo`` (batches of runs, one task each) to Ray and write each result as it comes (see
    :func:`run_campaign`)."""
    import ray

    from evoscen_experiments.timing import COMMAND, first_task_overheads

    started = not ray.is_initialized()
    if started:
        local = {} if address else {"num_cpus": cpus, "object_store_memory": OBJECT_STORE_BYTES}
        t_ray = time.monotonic()
        COMMAND.ray_at = t_ray if COMMAND.ray_at is None else COMMAND.ray_at
        ctx = ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False,
                       **local)
        result.ray_s = time.monotonic() - t_ray
        COMMAND.ray_s += result.ray_s
        if not address:  # this driver's own Ray: noted, so that the next driver can end what a kill leaves
            session = (getattr(ctx, "address_info", None) or {}).get("session_dir")
            if session:
                _note_driver(out_dir, session)
    arm()
    task = ray.remote(num_cpus=1, max_retries=retries, retry_exceptions=False)(execute_batch)
    pending = {task.remote(batch, str(out_dir), record, clip_s, time.time(), lockstep): batch for batch in todo}
    notes: list[dict[str, Any]] = []  # the computed runs' worker notes (execute_batch)
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
            for ref in ready:
                batch = pending.pop(ref)
                try:
                    answers = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - the task failed after its retries: all its runs
                    answers = [_failure(exc)] * len(batch)
                for run, done in zip(batch, answers):
                    if "worker" in done:
                        row = done["row"]
                        notes.append({**done["worker"], "worker": f"{row['node']}:{row['pid']}",
                                      "wall_s": row["wall_time_s"], "steps": row["steps"]})
                    _take(run, done, out_dir, result, total, progress)
    except (KeyboardInterrupt, _HostFaultStop) as exc:
        result.interrupted = isinstance(exc, KeyboardInterrupt)
        if not started:  # a cluster's workers outlive this driver: ask them to drop our tasks
            for ref in pending:
                with contextlib.suppress(Exception):
                    ray.cancel(ref)
        # (a local Ray goes down with its workers below; a forced cancel racing a task that
        # is just completing aborted the driver inside Ray, seen once on this machine)
    finally:
        overheads = first_task_overheads(notes)
        result.first_task_s = sum(overheads.values()) / len(overheads) if overheads else 0.0
        COMMAND.first_task_s += result.first_task_s
        if started:
            ray.shutdown()
            with contextlib.suppress(OSError):
                (out_dir / DRIVER_FILE).unlink()


def _note_driver(out_dir: Path, session_dir: str) -> None:
    with contextlib.suppress(OSError):  # only a help for the next start: never a reason to stop
        write_atomic(out_dir / DRIVER_FILE, json.dumps({"pid": os.getpid(), "start": start_time(os.getpid()),
                                                          "session_dir": session_dir}) + "\n")


def _take(run: CampaignRun, done: dict[str, Any], out_dir: Path, result: CampaignResult, total: int,
          progress: Callable[[int, int, float, float], None] | None) -> None:
    """One run's answer from its task: its files written (the run then counts as done), or its failure
    noted; a fault of the host stops the campaign (:class:`_HostFaultStop`)."""
    if "error" in done:
        if done["host_fault"] is not None:  # the worker's disk: every other run would fail alike
            path, cause = done["host_fault"]
            result.host_fault = f"run {run.key} (seed {run.seed}): cannot write {path} on its worker: {cause}"
            raise _HostFaultStop
        result.failed.append(f"{run.key} ({dict(run.cell)}, seed {run.seed}): {done['error']}")
        return
    path = result_path(out_dir, run.key)
    try:
        _write_files(path.parent, done["files"])
        write_atomic(path.with_name("scenario.yaml"), yaml.safe_dump(config_to_dict(run.cfg), sort_keys=False))
        write_atomic(path.with_name("report.json"), json.dumps(done["report"], indent=1) + "\n")
        write_atomic(path.with_name("plot.json"), json.dumps(done["plot"]) + "\n")
        write_atomic(path, json.dumps(done["row"]) + "\n")  # last: the run counts as done
    except OSError as exc:  # not marked done: the same command computes it again
        from evoscen_sim.errors import HostFault

        fault = HostFault.of(exc, exc.filename or path.parent)
        result.host_fault = f"run {run.key} (seed {run.seed}): {fault}"
        raise _HostFaultStop from None
    result.computed += 1
    result.nodes.add(done["row"]["node"])
    from evoscen_experiments.timing import COMMAND

    COMMAND.ran(done["row"]["steps"])
    if progress is not None:
        progress(result.already_done + result.computed, total, *COMMAND.rates())


class _HostFaultStop(Exception):
    """Stops the campaign's loop after a fault of the host (``CampaignResult.host_fault`` says which)."""


def load_result(out_dir: Path, key: str) -> dict[str, Any]:
    """A finished run's files: ``{"row", "report", "plot"}`` (``plot``: the SUT's TTC and speed
    histograms over :data:`evoscen_eval.scoring.plot_inputs.TTC_BINS` and ``SPEED_BINS``)."""
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
