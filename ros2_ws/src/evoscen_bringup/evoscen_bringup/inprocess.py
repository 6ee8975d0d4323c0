"""The in-process runner: simulation, drivers and recorder composed in one process.

No middleware: the cores are called directly, in the same order the node graph uses
(think ROS 2 composition). Step ``k`` (time ``t_k``):

1. the world at ``t_k`` is published: ``/clock``, ``/evoscen/world``, ``/evoscen/sut/odom``
   (and, once before the first step, the transient-local ``/evoscen/roster``);
2. the BV drivers and the SUT answer with their commands, stamped ``t_k``
   (``/evoscen/commands/bv``, ``/evoscen/commands/sut``);
3. the world integrates to ``t_{k+1}``; what happened goes out on ``/evoscen/events``
   stamped ``t_{k+1}`` (every step; empty when nothing happened).

After the last step the final state (``t_N``) is published too, and a ``run_end`` event.
With recording on, every message goes through :class:`evoscen_eval.recorder.OrderedBag`
and :class:`~evoscen_eval.recorder.BagRecorder` — what the evaluator node uses — with the
bytes of :class:`evoscen_contract.messages.WorldMessages` — what the simulation node
publishes — and log time = simulation time, so the bag is byte-identical for the same
config and seed, and equal to the node graph's.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable


from evoscen_contract.contract import KIND_COMPLETED, KIND_INTERRUPTED
from evoscen_sim.config import ScenarioConfig

from evoscen_sim.events import ExposureMonitor, run_end_event, step_events

from .scenario import Scenario, build_scenario


@dataclass
class RunSummary:
    """What a run did (printed by ``run_scenario.py``)."""

    steps: int
    sim_time_s: float
    wall_time_s: float
    bag_dir: Path | None
    collisions: int = 0
    lane_changes: int = 0
    reentries: int = 0
    off_road: int = 0
    message_count: int = 0
    bag_bytes: int = 0
    report: dict | None = None
    """The evaluation report (``report.json``'s content) when the run was evaluated."""
    run: object | None = None
    """The evaluated run as arrays (:class:`evoscen_eval.rundata.RunData`), with ``report``."""

    @property
    def steps_per_s(self) -> float:
        """Simulation steps per wall-clock second."""
        return self.steps / self.wall_time_s if self.wall_time_s > 0 else math.inf


class _Recorder:
    """The contract's messages of an in-process run, written through an ordered bag."""

    def __init__(self, bag_dir: Path, cfg: ScenarioConfig, road) -> None:  # noqa: ANN001
        from evoscen_contract import topics as T
        from evoscen_contract.messages import WorldMessages
        from evoscen_eval.recorder import BagRecorder, OrderedBag

        self.T = T
        self.msgs = WorldMessages(cfg.dt_s)
        from evoscen_eval.rundata import SCENARIO_METADATA, scenario_metadata

        bag = BagRecorder(bag_dir, T.CONTRACT, compression=cfg.recording.compression,
                          chunk_size=cfg.recording.chunk_size_bytes,
                          metadata={SCENARIO_METADATA: scenario_metadata(cfg)})
        self.bag = OrderedBag(bag, T.CONTRACT)
        self.road = road
        self.markers_every = cfg.recording.markers_every
        self.last_state_ns: int | None = None

    def world_state(self, world, sut_index: int, *, roster: bool = False) -> None:  # noqa: ANN001
        T, m, t_ns = self.T, self.msgs, world.time_ns
        self.last_state_ns = t_ns
        cols = world.columns()
        self.bag.flush_before(t_ns)
        if roster:
            self.bag.add(T.ROSTER.name, m.roster(cols, t_ns), t_ns, canonical=True)
            self.bag.add(T.MAP_MARKERS.name, m.map_markers(self.road, t_ns), t_ns)
        self.bag.add(T.CLOCK.name, m.clock(t_ns), t_ns, canonical=True)
        self.bag.add(T.WORLD.name, m.world(cols, t_ns), t_ns, canonical=True)
        self.bag.add(T.SUT_ODOM.name, m.odometry(cols, sut_index, t_ns), t_ns, canonical=True)
        if self.markers_every and world.step_index % self.markers_every == 0:
            self.bag.add(T.MARKERS.name, m.vehicle_markers(cols, t_ns), t_ns, canonical=True)

    def commands(self, topic: str, ids, throttle, lane_change, t_ns: int) -> None:  # noqa: ANN001
        self.bag.add(topic, self.msgs.commands(ids, throttle, lane_change, t_ns), t_ns, canonical=True)

    def events(self, events: list[dict], t_ns: int) -> None:
        self.bag.add(self.T.EVENTS.name, self.msgs.events(events, t_ns), t_ns)


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
) -> RunSummary:
    """Run ``steps`` (default ``cfg.steps``) steps; record to ``bag_dir`` unless it is None.

    With ``report_dir`` the run is scored and ``report.json``/``report.md`` (and, with
    ``plots``, the PNGs) are written there (:mod:`evoscen_eval.report`); with ``evaluate``
    alone the report is only returned (``RunSummary.report``). Either way the scores are the
    ones an offline evaluation of the bag gives.

    Ctrl-C (KeyboardInterrupt) ends the run after the current step: the bag is finished
    (``run_end`` event of kind ``interrupted``) and the interrupt is raised again.
    """
    sc = scenario if scenario is not None else build_scenario(cfg)
    n_steps = cfg.steps if steps is None else steps
    world = sc.world
    rec = _Recorder(bag_dir, cfg, world.road) if bag_dir is not None else None
    acc = None
    if report_dir is not None or evaluate:
        from evoscen_eval.rundata import RunAccumulator

        acc = RunAccumulator(expected_states=n_steps + 1)
        if report_dir is not None:  # the lane lines of the report's snapshots
            acc.add_map(world.road)
    exposures = ExposureMonitor(cfg.evaluation, world.role)
    initial = exposures.observe(world)  # an exposure in the initial state goes out with the first events
    bv_ids = world.ids[sc.bv_indices]
    sut_ids = world.ids[[sc.sut_index]]
    summary = RunSummary(steps=n_steps, sim_time_s=0.0, wall_time_s=0.0, bag_dir=bag_dir)
    end_kind, end_message = KIND_INTERRUPTED, "run interrupted"
    t0 = time.perf_counter()
    try:
        for k in range(n_steps):
            if rec is not None:
                rec.world_state(world, sc.sut_index, roster=(k == 0))
            if acc is not None:
                acc.add_world_columns(world.columns(), world.time_ns)
            bv_thr, bv_lc, sut_thr, sut_lc = sc.commands()
            if rec is not None:
                t_ns = world.time_ns
                if len(bv_ids):  # no BVs, no BV controller: no BV commands (as in the node graph)
                    rec.commands(rec.T.COMMANDS_BV.name, bv_ids, bv_thr, bv_lc, t_ns)
                rec.commands(rec.T.COMMANDS_SUT.name, sut_ids, sut_thr, sut_lc, t_ns)
            result = sc.apply(bv_thr, bv_lc, sut_thr, sut_lc)
            summary.collisions += len(result.collisions)
            summary.lane_changes += len(result.lane_changes_completed)
            summary.reentries += len(result.reentries)
            summary.off_road += len(result.off_road)
            events = initial + step_events(world, result) + exposures.observe(world)
            initial = []
            if rec is not None:
                rec.events(events, world.time_ns)  # every step, as the sim node
            if acc is not None:
                acc.add_events(events)
            if progress is not None:
                progress(k + 1)
        end_kind, end_message = KIND_COMPLETED, f"run completed: {world.step_index} steps"
    finally:
        summary.wall_time_s = time.perf_counter() - t0
        summary.steps = world.step_index
        summary.sim_time_s = world.time_s
        end = [run_end_event(world, end_kind, end_message)]
        if rec is not None:
            if rec.last_state_ns != world.time_ns:  # the final state, unless recorded already (Ctrl-C)
                rec.world_state(world, sc.sut_index, roster=(world.step_index == 0))
            rec.events(end, world.time_ns)
            rec.bag.close()
            summary.message_count = rec.bag.message_count
            summary.bag_bytes = sum(f.stat().st_size for f in Path(bag_dir).iterdir())
        if acc is not None:
            if acc.states == world.step_index:  # the final state, unless collected already (Ctrl-C)
                acc.add_world_columns(world.columns(), world.time_ns)
            acc.add_events(end)
    if acc is not None:
        summary.run, summary.report = _report(acc, cfg, report_dir, plots)
    return summary


def _report(acc, cfg: ScenarioConfig, report_dir: Path | None, plots: bool):  # noqa: ANN001, ANN202
    """Score the accumulated run exactly as the bag would be scored (same scenario dict)."""
    import yaml

    from evoscen_eval.metrics import evaluate
    from evoscen_eval.report import evaluation_settings, write_report
    from evoscen_eval.rundata import SCENARIO_KEY, scenario_metadata

    run = acc.run_data(scenario=yaml.safe_load(scenario_metadata(cfg)[SCENARIO_KEY]))
    if report_dir is None:
        return run, evaluate(run, evaluation_settings(run))
    return run, write_report(run, report_dir, plots=plots)
