"""The in-process runner: simulation, drivers and recorder composed in one process.

No middleware: the cores are called directly. The steps are run by the step loop the
simulation node drives too (:class:`evoscen_sim.loop.step_loop.StepLoop`: state at ``t_k`` out,
commands in, the world integrates to ``t_{k+1}``, its events out with the next state; after
the last step the final state and a ``run_end`` event); this runner's port asks the BV
drivers and the SUT for the commands directly (think ROS 2 composition) and records every
message. :func:`run_inprocess` resolves the configuration once into the run's plan
(:mod:`evoscen_bringup.plan`) and :func:`run_plan` runs it, each room with its part.

With recording on, every message goes to :class:`~evoscen_record.recorder.BagRecorder` — what the
evaluator node uses — in the canonical order :class:`evoscen_record.ordered_bag.OrderedBag` gives
(a step at a time, :class:`~evoscen_record.step_recorder.StepRecorder`), with the bytes of
:class:`evoscen_contract.messages.WorldMessages` — what the simulation node publishes — and log
time = simulation time, so the bag is byte-identical for the same config and seed, and equal
to the node graph's.
"""

from __future__ import annotations

import copy
import math
import signal
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from evoscen_contract.contract import KIND_ABORT, KIND_INTERRUPTED, NODE_SUT
from evoscen_record.step_recorder import StepRecorder
from evoscen_sim.config.scenario_config import ScenarioConfig
from evoscen_sim.danger.events import fault_event
from evoscen_sim.errors import PluginFault
from evoscen_sim.loop.step_loop import Commands, Port, StepLoop

from evoscen_bringup.plan import DriverPlan, EvaluationPlan, RunPlan, plan_of
from evoscen_bringup.scenario import Scenario


@dataclass
class RunSummary:
    """What a run did (printed by ``run_scenario.py``)."""

    steps: int
    sim_time_s: float
    wall_time_s: float
    """From step 0 until the bag is closed (s)."""
    bag_dir: Path | None
    steps_wall_s: float = 0.0
    """From step 0 to the end of the last step (s): what ``steps_per_s`` and a progress bar measure."""
    report_wall_s: float = 0.0
    """Scoring's end and the report's writing after the last step (s)."""
    collisions: int = 0
    """Of all vehicles, as ``lane_changes``, ``reentries`` and ``off_road``."""
    lane_changes: int = 0
    sut_lane_changes: int = 0
    """Lane changes the SUT completed."""
    reentries: int = 0
    off_road: int = 0
    message_count: int = 0
    bag_bytes: int = 0
    report: dict | None = None
    """The evaluation report (``report.json``'s content) when the run was evaluated."""
    run: object | None = None
    """The evaluated run as arrays (:class:`evoscen_eval.scoring.rundata.RunData`), with ``keep_run``."""
    plot: object | None = None
    """The evaluated run's :class:`evoscen_eval.scoring.plot_inputs.PlotData` (distributions of TTC and speed)."""

    @property
    def steps_per_s(self) -> float:
        """Simulation steps per wall-clock second, the bag's closing included (``wall_time_s``)."""
        return self.steps / self.wall_time_s if self.wall_time_s > 0 else math.inf

    @property
    def stepping_steps_per_s(self) -> float:
        """Simulation steps per wall-clock second of stepping (``steps_wall_s``): a progress bar's rate."""
        return self.steps / self.steps_wall_s if self.steps_wall_s > 0 else math.inf


class _CtrlC:
    """Ctrl-C during an in-process run takes effect at the next step boundary, as in the
    simulation node: the first SIGINT is noted and :meth:`_InProcessPort.begin_step` raises
    KeyboardInterrupt, so a state is never recorded half (its world without its ``/clock``); a
    second SIGINT raises at once (a step that hangs can still be left). Installed only in the
    main thread over Python's default handler (a caller's own handler, or SIGINT ignored, is
    left alone); the earlier handler is back when the run's bag is closed."""

    def __init__(self) -> None:
        self.pending = False
        self._previous = None

    def __enter__(self) -> _CtrlC:
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def _on_sigint(self, signum, frame) -> None:
        if self.pending:
            raise KeyboardInterrupt
        self.pending = True

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


class _InProcessPort(Port):
    """The in-process runner's side of the step loop: the drivers answer, the bag records.

    Messages go to the bag (``rec``) and/or the evaluator's accumulator (``acc``), either of
    which may be absent. The bag writes each step in canonical order, so the order of the
    calls within a step does not show in it.
    """

    def __init__(self, sc: Scenario, drivers: DriverPlan, rec: StepRecorder | None, acc, summary: RunSummary,
                 progress: Callable[[int], None] | None) -> None:
        self.sc, self.rec, self.acc, self.summary, self.progress = sc, rec, acc, summary, progress
        self.bv_ids = sc.world.ids[sc.bv_indices]
        self.sut_ids = sc.world.ids[[sc.sut_index]]
        self._cols = None  # the columns of the state being sent
        self.ctrl_c: _CtrlC | None = None
        self.fault: PluginFault | None = None  # a driver that raised (the run was aborted)
        self.bv_node = drivers.fault_node  # the BV node named in a BV driver's fault

    def start(self) -> None:
        """``progress(0)``: step 0 begins (a progress bar's clock starts here, as ``steps_wall_s``)."""
        if self.progress is not None:
            self.progress(0)

    def begin_step(self, step: int) -> None:
        """A noted Ctrl-C takes effect here (:class:`_CtrlC`)."""
        if self.ctrl_c is not None and self.ctrl_c.pending:
            raise KeyboardInterrupt

    def send_world(self, world, *, roster: bool) -> None:
        rec, acc = self.rec, self.acc
        if rec is None and acc is not None:  # scored, no bag: the table in one compiled pass (World.table)
            self._cols = None
            acc.add_world_table(world.table(), world.time_ns)
            return
        # the columns when someone here reads them (the process writer copies the state instead)
        need = acc is not None or (rec is not None and not rec.snapshots)
        self._cols = cols = world.columns() if need else None
        if rec is not None:
            rec.world(world, cols, world.time_ns, roster=roster)
        if acc is not None:
            acc.add_world_columns(cols, world.time_ns)

    def send_events(self, events: list[dict], t_ns: int) -> None:
        if self.rec is not None:
            self.rec.events(events, t_ns)  # every step, as the sim node
        if self.acc is not None:
            self.acc.add_events(events)

    def send_state(self, world) -> None:
        if self.rec is not None:
            self.rec.state(world, self._cols, self.sc.sut_index, world.step_index, world.time_ns)
        self._cols = None

    def commands(self, step: int) -> Commands:
        sc, rec = self.sc, self.rec
        try:
            bv_thr, bv_lc, sut_thr, sut_lc = sc.commands()
        except PluginFault as fault:  # a driver raised: the run is aborted here, as the graph's simulation does
            self.fault = fault
            controller = NODE_SUT if fault.role == "sut" else self.bv_node
            event = fault_event(sc.world, KIND_ABORT, controller, 1, str(fault))
            empty = np.empty(0)
            return Commands(empty, empty, [[event]], abort=f"controller '{controller}' failed at step {step}; run aborted")
        if rec is not None:
            t_ns = sc.world.time_ns
            if len(self.bv_ids):  # no BVs, no BV controller: no BV commands (as in the node graph)
                rec.bv_commands(self.bv_ids, bv_thr, bv_lc, t_ns)  # one message per BV node (bvs.nodes)
            rec.commands(rec.T.COMMANDS_SUT.name, self.sut_ids, sut_thr, sut_lc, t_ns)
        throttle, lane_change = sc.assemble(bv_thr, bv_lc, sut_thr, sut_lc)
        return Commands(throttle, lane_change)

    def stepped(self, step: int, result) -> None:
        s = self.summary
        s.collisions += len(result.collisions)
        s.lane_changes += len(result.lane_changes_completed)
        s.sut_lane_changes += sum(1 for c in result.lane_changes_completed if c[0] == self.sc.sut_index)
        s.reentries += len(result.reentries)
        s.off_road += len(result.off_road)
        if self.progress is not None:
            self.progress(step + 1)


def run_inprocess(
    cfg: ScenarioConfig,
    *,
    bag_dir: Path | None,
    steps: int | None = None,
    progress: Callable[[int], None] | None = None,
    scenario: Scenario | None = None,
    report_dir: Path | None = None,
    evaluate: bool = False,
    plots: bool = True,
    keep_run: bool = False,
    bag_writer: str = "auto",
) -> RunSummary:
    """Run ``steps`` (default ``cfg.steps``) steps of ``cfg``; record to ``bag_dir`` unless it is None.

    The configuration is resolved once, here, into the run's plan (:func:`evoscen_bringup.plan.plan_of`;
    ``scenario``: the built world and drivers to run, default built from ``cfg``), which
    :func:`run_plan` runs: see there for the other arguments, the report and the errors.
    """
    plan = plan_of(cfg, recorded=bag_dir is not None, steps=steps, scenario=scenario)
    return run_plan(plan, bag_dir=bag_dir, progress=progress, report_dir=report_dir, evaluate=evaluate,
                    plots=plots, keep_run=keep_run, bag_writer=bag_writer)


def run_plan(
    plan: RunPlan,
    *,
    bag_dir: Path | None,
    progress: Callable[[int], None] | None = None,
    report_dir: Path | None = None,
    evaluate: bool = False,
    plots: bool = True,
    keep_run: bool = False,
    bag_writer: str = "auto",
) -> RunSummary:
    """Run ``plan.steps`` steps of ``plan``; record to ``bag_dir`` unless it is None (a plan of a
    recorded run: ``plan.recording``). Each room gets its part of the plan: the recorder the recording
    part, the step loop and the scorer the evaluation settings.

    ``progress(k)`` is told ``0`` as step 0 begins and ``k`` as step k − 1 ends (a progress bar's clock
    and ``RunSummary.steps_wall_s`` measure the same span). With ``report_dir`` the run is scored and ``report.json``/``report.md`` (and, with
    ``plots``, the PNGs) are written there (:mod:`evoscen_eval.scoring.report`); with ``evaluate``
    alone the report is only returned (``RunSummary.report``). Either way the scores are the
    ones an offline evaluation of the bag gives, computed as the run goes (scoring memory does
    not grow with the run); ``keep_run`` also keeps the run's arrays (``RunSummary.run``).

    ``bag_writer`` ([choice] bag writer, docs/recording.md): ``"inline"`` writes the bag in this
    process, between the steps; ``"process"`` hands it to a forked writer process
    (:mod:`evoscen_record.bag_writer`), the same bytes; ``"auto"`` (default) is the process writer
    when this process may use more than one CPU. ``wall_time_s`` runs from step 0 until the bag is
    closed.

    Ctrl-C ends the run at the next step boundary (:class:`_CtrlC`): the bag is finished
    (``run_end`` event of kind ``interrupted``) and KeyboardInterrupt is raised; any other error
    also finishes the bag and is raised again. A fault of the host (a full disk, an output
    directory made read-only or removed) is :class:`~evoscen_sim.errors.HostFault`, raised at
    the step boundary after the failed write, with the bag finished from every step that reached
    the disk, or cut back to them for ``scripts/reindex.py`` when there is no room to finish it
    (``HostFault.bag_state``); a report that cannot be written is one too, the bag finished. A Ctrl-C after the last step began lets the run
    complete and then raises KeyboardInterrupt. A driver that raises ends the run ``aborted`` at that
    step (a ``fault`` event of kind ``abort`` naming it, then ``run_end``), the bag finished, and
    :class:`~evoscen_sim.errors.PluginFault` is raised (``bag_dir``, ``steps`` set); the run is not
    scored.
    """
    if bag_dir is not None and plan.recording is None:
        raise ValueError("bag_dir given for a plan without a recording part (plan_of(..., recorded=False))")
    scored = report_dir is not None or evaluate
    acc, summary = _scoring(plan, bag_dir, report_dir, plots, keep_run) if scored else (None, None)
    if summary is None:
        summary = RunSummary(steps=plan.steps, sim_time_s=0.0, wall_time_s=0.0, bag_dir=bag_dir)
    rec = None
    if bag_dir is not None:
        from evoscen_record.bag_writer import ProcessRecorder, resolve_writer

        world = plan.scenario.world
        if resolve_writer(bag_writer) == "process":
            rec = ProcessRecorder(bag_dir, plan.recording, world)
        else:
            rec = StepRecorder(bag_dir, plan.recording, world.road)
    with _CtrlC() as ctrl_c:
        try:  # from here on the bag is closed, whatever happens
            port, loop = _loop(plan, rec, acc, summary, progress, ctrl_c)
            outcome = loop.run(plan.steps)
        finally:
            t_close = time.perf_counter()
            if rec is not None:
                rec.close()
            t_close = time.perf_counter() - t_close
    if ctrl_c.pending:  # noted after the last step began: the run completed, the user asked to stop
        raise KeyboardInterrupt
    return _finish(plan, outcome, port, acc, summary, bag_dir, rec, t_close, report_dir, plots, keep_run)


def run_plans(plans: Sequence[RunPlan], *, keep_run: bool = False) -> list[RunSummary | Exception]:
    """Unrecorded runs scored as :func:`run_plan` scores them (``evaluate=True``, no report written), stepped in
    lockstep in this process: step ``k`` of every run, then step ``k + 1`` (docs/performance.md "Many worlds at
    once"). Each run's :class:`RunSummary`, equal to its :func:`run_plan`'s (its report and plot data the same;
    ``steps_wall_s`` and ``wall_time_s`` its share of the batch's wall time), or the exception its run ended with
    (a :class:`~evoscen_sim.errors.PluginFault` for a driver that raised, a ValueError …), in the order of
    ``plans``; a run that fails (in its set-up, a step or its scoring; a
    :class:`~evoscen_sim.errors.HostFault` too, as :func:`run_plan` would raise it for that run alone) ends
    alone, its exception in its place, and leaves the others going. Ctrl-C ends every run at its next step
    boundary (``interrupted``) and raises KeyboardInterrupt."""
    if any(plan.recording is not None for plan in plans):
        raise ValueError("run_plans: plans of unrecorded runs only (plan_of(..., recorded=False))")
    out: list[RunSummary | Exception | None] = [None] * len(plans)
    runs = []
    with _CtrlC() as ctrl_c:
        for j, plan in enumerate(plans):
            try:
                acc, summary = _scoring(plan, None, None, False, keep_run)
                port, loop = _loop(plan, None, acc, summary, None, ctrl_c)
            except Exception as exc:  # noqa: BLE001 - this run's own error: the others go on
                out[j] = exc
                continue
            runs.append((j, plan, acc, summary, port, loop.stepping(plan.steps)))
        t0 = time.perf_counter()
        outcomes: dict[int, object] = {}
        live = runs
        while live:
            going = []
            for run in live:
                try:
                    next(run[5])
                    going.append(run)
                except StopIteration as done:
                    outcomes[run[0]] = done.value
                except Exception as exc:  # noqa: BLE001 - this run's own error: it ends here, the others go on
                    out[run[0]] = exc
            live = going
        share = (time.perf_counter() - t0) / max(len(runs), 1)
    if ctrl_c.pending or any(getattr(o, "kind", None) == KIND_INTERRUPTED for o in outcomes.values()):
        raise KeyboardInterrupt
    for j, plan, acc, summary, port, _ in runs:
        if j in outcomes:
            outcome = outcomes[j]
            outcome.wall_s = share
            try:
                out[j] = _finish(plan, outcome, port, acc, summary, None, None, 0.0, None, False, keep_run)
            except Exception as exc:  # noqa: BLE001 - a driver's fault (PluginFault), a scoring error: this run's
                out[j] = exc
    return out  # type: ignore[return-value]


def _scoring(plan: RunPlan, bag_dir: Path | None, report_dir: Path | None, plots: bool, keep_run: bool):
    """The run's evaluator accumulator (scoring as the states come) and its summary to fill."""
    from evoscen_eval.scoring.rundata import RunAccumulator

    n_steps, ev = plan.steps, plan.evaluation
    acc = RunAccumulator(expected_states=n_steps + 1, keep_world=keep_run)
    # the settings an evaluation of the bag reads back; the animation's frames only for a report with plots
    acc.start_scoring(ev.settings, ev.dt_s, frames=report_dir is not None and plots)
    if report_dir is not None:  # the lane lines of the report's snapshots
        acc.add_map(plan.scenario.world.road)
    return acc, RunSummary(steps=n_steps, sim_time_s=0.0, wall_time_s=0.0, bag_dir=bag_dir)


def _loop(plan: RunPlan, rec, acc, summary: RunSummary, progress, ctrl_c: _CtrlC) -> tuple[_InProcessPort, StepLoop]:
    """The run's port and step loop."""
    port = _InProcessPort(plan.scenario, plan.drivers, rec, acc, summary, progress)
    port.ctrl_c = ctrl_c
    loop = StepLoop(plan.scenario.world, plan.evaluation.settings, port, interrupted_text="run interrupted",
                    finish_on_error=True)
    return port, loop


def _finish(plan: RunPlan, outcome, port: _InProcessPort, acc, summary: RunSummary, bag_dir: Path | None, rec,
            t_close: float, report_dir: Path | None, plots: bool, keep_run: bool) -> RunSummary:
    """The run's summary after its loop ended (:func:`run_plan`'s errors raised), scored when ``acc``."""
    world, ev = plan.scenario.world, plan.evaluation
    summary.wall_time_s = outcome.wall_s + t_close if outcome.wall_s is not None else outcome.wall_s
    summary.steps_wall_s = outcome.wall_s if outcome.wall_s is not None else 0.0
    summary.steps = world.step_index
    summary.sim_time_s = world.time_s
    if rec is not None:
        summary.message_count = rec.message_count
        summary.bag_bytes = sum(f.stat().st_size for f in Path(bag_dir).iterdir())
    if outcome.kind == KIND_INTERRUPTED:
        raise KeyboardInterrupt
    if port.fault is not None:  # a driver raised: the bag is finished (run_end aborted); not scored
        port.fault.bag_dir, port.fault.steps = bag_dir, summary.steps + 1
        raise port.fault
    if acc is not None:
        from evoscen_sim.errors import HostFault

        try:
            t_report = time.perf_counter()
            summary.run, summary.report, summary.plot = _report(acc, ev, report_dir, plots, keep_run)
            summary.report_wall_s = time.perf_counter() - t_report
        except HostFault as fault:  # a full disk, a read-only report directory: the bag is finished
            fault.bag_dir, fault.steps = bag_dir, summary.steps + 1
            fault.bag_state = "finished" if bag_dir is not None else None
            raise
        except OSError as exc:
            raise HostFault.of(exc, exc.filename or report_dir, bag_dir=bag_dir, steps=summary.steps + 1,
                               bag_state="finished" if bag_dir is not None else None) from None
    return summary


def _report(acc, ev: EvaluationPlan, report_dir: Path | None, plots: bool, keep_run: bool):
    """Score the run as it was streamed, exactly as the bag would be scored (``ev.scenario``: the
    scenario as the bag records it)."""
    from evoscen_eval.scoring.metrics import report_of_stream
    from evoscen_eval.scoring.report import write_stream_report

    info = acc.stream_info(scenario=ev.scenario)
    run = acc.run_data(scenario=copy.deepcopy(ev.scenario)) if keep_run else None
    if report_dir is None:
        report = report_of_stream(acc.stream, info, [])
    else:
        report = write_stream_report(acc.stream, info, [], report_dir, plots=plots, lane_segments=acc.lane_segments)
    return run, report, acc.stream.plot_data()
