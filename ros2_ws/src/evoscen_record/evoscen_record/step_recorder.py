"""The in-process runner's recorder: a run's messages written a step at a time in canonical order.

Used inline by :func:`evoscen_bringup.inprocess.run_plan` and, in the writer process, by
:mod:`evoscen_record.bag_writer` (docs/recording.md, "[choice] the bag written inline or by a
writer process"). It takes the run's recording part
(:class:`~evoscen_record.recording_plan.RecordingPlan`), not the scenario's configuration.
"""

from __future__ import annotations

from pathlib import Path

from evoscen_record.recording_plan import RecordingPlan


class StepRecorder:
    """The contract's messages of an in-process run, written a step at a time in canonical order.

    Every message of a step carries the world's time and the world's message comes first (the
    step loop's order), so a step is complete when the next world arrives or the run closes; it is
    then written in the contract's topic order, arrival order within a topic — the order
    :class:`~evoscen_record.ordered_bag.OrderedBag` gives — by one
    :meth:`~evoscen_record.recorder.BagRecorder.write_parts` call, the tables, clock and odometry as
    the pieces of their bytes. ``direct = False`` is the earlier path (every message through the
    ordered bag); tests/test_recording_paths.py records a run both ways and compares the files.
    """

    direct: bool = True

    def __init__(self, bag_dir: Path, recording: RecordingPlan, road) -> None:
        """Open the bag ``bag_dir`` for a run of the recording part ``recording`` on ``road`` (the map
        markers' lines)."""
        import numpy as np
        from evoscen_contract import topics as T
        from evoscen_contract.messages import WorldMessages

        from evoscen_record.ordered_bag import OrderedBag
        from evoscen_record.recorder import BagRecorder
        from evoscen_record.reindex import finish_bag
        from evoscen_record.scenario_record import SCENARIO_METADATA

        self.T = T
        self.msgs = WorldMessages(recording.dt_s)
        # the BV nodes of bvs.nodes, each with its command topic (the graph's: docs/architecture.md
        # §5, "BV nodes"); positions: where its BVs are among all BVs
        contract = T.contract_for(recording.bv_nodes)
        self.bv_parts = [(b.topic, np.asarray(b.positions, dtype=np.intp)) for b in recording.bv_topics]
        bag = BagRecorder(bag_dir, contract, compression=recording.compression,
                          chunk_size=recording.chunk_size_bytes,
                          metadata={SCENARIO_METADATA: dict(recording.scenario_record)}, finish_after_fault=finish_bag)
        self.bag = OrderedBag(bag, contract)
        self.road = road
        self.markers_every = recording.markers_every
        self._direct = self.direct
        self._rank = {spec.name: k for k, spec in enumerate(contract)}
        self._slots: list[list] = [[] for _ in contract]  # the open step's (topic, pieces), by topic rank
        self._t: int | None = None  # its time
        self._pending = False

    def _add(self, topic: str, parts: tuple, t_ns: int) -> None:
        """Queue a message of the open step (as pieces of its bytes)."""
        if t_ns != self._t:
            self._write_step()
            self._t = t_ns
        self._slots[self._rank[topic]].append((topic, parts))
        self._pending = True

    def _write_step(self) -> None:
        """Write the open step's messages in canonical order (nothing if none)."""
        if self._pending:
            messages = [m for slot in self._slots if slot for m in slot]
            for slot in self._slots:
                slot.clear()
            self._pending = False
            self.bag.bag.write_parts(self._t, messages)

    def close(self) -> None:
        """Write what is queued and finish the bag (idempotent); after a fault of the host
        (:class:`~evoscen_sim.errors.HostFault`) the bag is finished from what reached the disk."""
        try:
            if self._direct:
                self._write_step()
        finally:
            self.bag.close()

    snapshots = False  # world/state use the columns (ProcessRecorder: the World)

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return self.bag.message_count

    def world(self, world, cols, t_ns: int, *, roster: bool) -> None:
        """``/evoscen/world`` (and the roster and map markers) at ``t_ns``; earlier steps are written.

        ``cols``: the world's columns (``world.columns()``; ``world`` is not used)."""
        T, m = self.T, self.msgs
        if self._direct:
            self._add(T.WORLD.name, m.world_parts(cols, t_ns), t_ns)
            if roster:
                self._add(T.ROSTER.name, (m.roster(cols, t_ns),), t_ns)
                self._add(T.MAP_MARKERS.name, (m.map_markers(self.road, t_ns),), t_ns)
            return
        self.bag.flush_before(t_ns)
        if roster:
            self.bag.add(T.ROSTER.name, m.roster(cols, t_ns), t_ns, canonical=True)
            self.bag.add(T.MAP_MARKERS.name, m.map_markers(self.road, t_ns), t_ns, canonical=True)
        self.bag.add(T.WORLD.name, m.world(cols, t_ns), t_ns, canonical=True)

    def state(self, world, cols, sut_index: int, step_index: int, t_ns: int) -> None:
        """The rest of the state: ``/clock``, odometry, vehicle markers when due."""
        T, m = self.T, self.msgs
        markers = self.markers_every and step_index % self.markers_every == 0
        if self._direct:
            self._add(T.CLOCK.name, m.clock_parts(t_ns), t_ns)
            self._add(T.SUT_ODOM.name, m.odometry_parts(cols, sut_index, t_ns), t_ns)
            if markers:
                self._add(T.MARKERS.name, (m.vehicle_markers(cols, t_ns),), t_ns)
            return
        self.bag.add(T.CLOCK.name, m.clock(t_ns), t_ns, canonical=True)
        self.bag.add(T.SUT_ODOM.name, m.odometry(cols, sut_index, t_ns), t_ns, canonical=True)
        if markers:
            self.bag.add(T.MARKERS.name, m.vehicle_markers(cols, t_ns), t_ns, canonical=True)

    def commands(self, topic: str, ids, throttle, lane_change, t_ns: int) -> None:
        if self._direct:
            self._add(topic, self.msgs.commands_parts(ids, throttle, lane_change, t_ns), t_ns)
        else:
            self.bag.add(topic, self.msgs.commands(ids, throttle, lane_change, t_ns), t_ns, canonical=True)

    def bv_commands(self, ids, throttle, lane_change, t_ns: int) -> None:
        """The commands of all BVs (in world-index order), one message per BV node on its topic, as the
        BV nodes of the graph answer (an empty table from a node without BVs)."""
        for topic, pos in self.bv_parts:
            self.commands(topic, ids[pos], throttle[pos], lane_change[pos], t_ns)

    def events(self, events: list[dict], t_ns: int) -> None:
        # canonical CDR already (evoscen_contract.cdr): no re-serialization
        if self._direct:
            self._add(self.T.EVENTS.name, (self.msgs.events(events, t_ns),), t_ns)
        else:
            self.bag.add(self.T.EVENTS.name, self.msgs.events(events, t_ns), t_ns, canonical=True)
