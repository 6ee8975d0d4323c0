"""The in-process runner: simulation, drivers and recorder composed in one process.

No middleware: the cores are called directly, in the same order the node graph uses
(think ROS 2 composition). Step ``k`` (time ``t_k``):

1. the world at ``t_k`` is published: ``/clock``, ``/evoscen/world``, ``/evoscen/sut/odom``
   (and, once before the first step, the transient-local ``/evoscen/roster``);
2. the BV drivers and the SUT answer with their commands, stamped ``t_k``
   (``/evoscen/commands/bv``, ``/evoscen/commands/sut``);
3. the world integrates to ``t_{k+1}``; what happened goes out on ``/evoscen/events``
   stamped ``t_{k+1}`` (only in steps where something happened).

After the last step the final state (``t_N``) is published too. With recording on, every
message goes through :class:`evoscen_eval.recorder.BagRecorder` — the same recorder the
evaluator node uses — serialized with ``rclpy.serialization``, log time = simulation
time, so the bag is byte-identical for the same config and seed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from evoscen_sim.config import ScenarioConfig

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

    @property
    def steps_per_s(self) -> float:
        """Simulation steps per wall-clock second."""
        return self.steps / self.wall_time_s if self.wall_time_s > 0 else math.inf


def step_events(world, result) -> list[dict]:  # noqa: ANN001
    """The ``/evoscen/events`` entries of one world step, in a fixed order."""
    ids = world.ids
    common = {"step": result.step, "time_s": result.time_s}
    events: list[dict] = []
    for i, j in result.collisions:
        events.append({"name": "evoscen/collision", "message": f"vehicles {ids[i]} and {ids[j]} collide",
                       **common, "ids": [int(ids[i]), int(ids[j])]})
    for i, from_lane, to_lane, duration in result.lane_changes_completed:
        events.append({"name": "evoscen/lane_change", "message": f"vehicle {ids[i]}: lane {from_lane} -> {to_lane}",
                       **common, "ids": [int(ids[i])], "duration_s": duration,
                       "direction": 1 if to_lane > from_lane else -1, "from_lane": from_lane, "to_lane": to_lane,
                       "kind": "completed"})
    for i, from_lane, to_lane in result.lane_changes_aborted:
        events.append({"name": "evoscen/lane_change", "level": 1,
                       "message": f"vehicle {ids[i]}: lane change {from_lane} -> {to_lane} aborted, lane {to_lane} ended",
                       **common, "ids": [int(ids[i])], "direction": 1 if to_lane > from_lane else -1,
                       "from_lane": from_lane, "to_lane": to_lane, "kind": "aborted"})
    for i, lane, s in result.reentries:
        events.append({"name": "evoscen/reentry", "message": f"vehicle {ids[i]} re-entered lane {lane} at s = {s:.1f} m",
                       **common, "ids": [int(ids[i])], "to_lane": lane})
    for i in result.off_road:
        events.append({"name": "evoscen/off_road", "message": f"vehicle {ids[i]} left the road",
                       **common, "ids": [int(ids[i])]})
    return events


class _Publisher:
    """Builds and records the contract's messages for the in-process runner.

    Tables, ``/clock`` and the odometry are encoded straight to canonical CDR
    (:mod:`evoscen_contract.cdr`); events go through rclpy's serializer and the recorder's
    canonical form.
    Either way the bytes equal what the recorder stores for the same message from the wire.
    """

    def __init__(self, bag_dir: Path, cfg: ScenarioConfig) -> None:
        from evoscen_contract import topics as T
        from evoscen_contract.cdr import OdometryEncoder, TableEncoder, encode_clock
        from evoscen_eval.recorder import BagRecorder
        from rclpy.serialization import serialize_message

        self.T = T
        self.serialize = serialize_message
        self.encode_clock = encode_clock
        self.world_table = TableEncoder(T.WORLD_FIELDS, T.MAP_FRAME)
        self.command_table = TableEncoder(T.COMMAND_FIELDS, T.MAP_FRAME)
        self.roster_table = TableEncoder(T.ROSTER_FIELDS, T.MAP_FRAME)
        self.odometry = OdometryEncoder(T.MAP_FRAME, T.SUT_BASE_FRAME)
        self.bag = BagRecorder(bag_dir, T.CONTRACT, compression=cfg.recording.compression,
                               chunk_size=cfg.recording.chunk_size_bytes)
        self._prev_yaw: float | None = None

    def _write(self, topic: str, msg, t_ns: int) -> None:  # noqa: ANN001
        self.bag.write(topic, self.serialize(msg), t_ns)

    def roster(self, world) -> None:  # noqa: ANN001
        cols = world.columns()
        data = np.column_stack([cols[f] for f in self.T.ROSTER_FIELDS])
        self.bag.write(self.T.ROSTER.name, self.roster_table.encode(data, world.time_ns), world.time_ns, canonical=True)

    def world_state(self, world, sut_index: int) -> None:  # noqa: ANN001
        T = self.T
        t_ns = world.time_ns
        cols = world.columns()
        data = np.column_stack([cols[f] for f in T.WORLD_FIELDS])
        self.bag.write(T.CLOCK.name, self.encode_clock(t_ns), t_ns, canonical=True)
        self.bag.write(T.WORLD.name, self.world_table.encode(data, t_ns), t_ns, canonical=True)
        yaw = float(cols["yaw"][sut_index])
        yaw_rate = 0.0 if self._prev_yaw is None else (yaw - self._prev_yaw) / world.dt_s
        self._prev_yaw = yaw
        odom = self.odometry.encode(cols["x"][sut_index], cols["y"][sut_index], yaw, cols["speed"][sut_index], yaw_rate, t_ns)
        self.bag.write(T.SUT_ODOM.name, odom, t_ns, canonical=True)

    def commands(self, topic: str, ids: np.ndarray, throttle: np.ndarray, lane_change: np.ndarray, t_ns: int) -> None:
        data = np.column_stack([ids, throttle, lane_change])
        self.bag.write(topic, self.command_table.encode(data, t_ns), t_ns, canonical=True)

    def events(self, events: list[dict], t_ns: int) -> None:
        self._write(self.T.EVENTS.name, self.T.events_message(events, t_ns), t_ns)


def run_inprocess(
    cfg: ScenarioConfig,
    *,
    bag_dir: Path | None,
    steps: int | None = None,
    progress: Callable[[int], None] | None = None,
    scenario: Scenario | None = None,
) -> RunSummary:
    """Run ``steps`` (default ``cfg.steps``) steps; record to ``bag_dir`` unless it is None."""
    sc = scenario if scenario is not None else build_scenario(cfg)
    n_steps = cfg.steps if steps is None else steps
    world = sc.world
    pub = _Publisher(bag_dir, cfg) if bag_dir is not None else None
    bv_ids = world.ids[sc.bv_indices]
    sut_ids = world.ids[[sc.sut_index]]
    summary = RunSummary(steps=n_steps, sim_time_s=0.0, wall_time_s=0.0, bag_dir=bag_dir)
    t0 = time.perf_counter()
    try:
        if pub is not None:
            pub.roster(world)
        for k in range(n_steps):
            if pub is not None:
                pub.world_state(world, sc.sut_index)
            bv_thr, bv_lc, sut_thr, sut_lc = sc.commands()
            if pub is not None:
                t_ns = world.time_ns
                pub.commands(pub.T.COMMANDS_BV.name, bv_ids, bv_thr, bv_lc, t_ns)
                pub.commands(pub.T.COMMANDS_SUT.name, sut_ids, sut_thr, sut_lc, t_ns)
            result = sc.apply(bv_thr, bv_lc, sut_thr, sut_lc)
            summary.collisions += len(result.collisions)
            summary.lane_changes += len(result.lane_changes_completed)
            summary.reentries += len(result.reentries)
            summary.off_road += len(result.off_road)
            if pub is not None and (result.collisions or result.lane_changes_completed or result.lane_changes_aborted
                                    or result.reentries or result.off_road):
                pub.events(step_events(world, result), world.time_ns)
            if progress is not None:
                progress(k + 1)
        if pub is not None:
            pub.world_state(world, sc.sut_index)
    finally:
        summary.wall_time_s = time.perf_counter() - t0
        summary.steps = world.step_index
        summary.sim_time_s = world.time_s
        if pub is not None:
            pub.bag.close()
            summary.message_count = pub.bag.message_count
            summary.bag_bytes = sum(f.stat().st_size for f in Path(bag_dir).iterdir())
    return summary
