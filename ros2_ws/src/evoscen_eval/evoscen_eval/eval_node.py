"""The evaluator node: records every contract topic into a rosbag2 (MCAP) bag and scores the run.

    python -m evoscen_eval.eval_node --ros-args --params-file eval.yaml -p bag_dir:=runs/x/bag

Raw (serialized) subscriptions on every topic of the contract, with the contract's QoS;
the bytes go through the same :class:`~evoscen_record.ordered_bag.OrderedBag` and
:class:`~evoscen_record.recorder.BagRecorder` as the in-process runner, so a graph run's bag
equals the in-process bag of the same scenario. Messages of one step arrive from several
publishers in no fixed order; every per-step topic carries exactly one message per step, in
order, so a step is complete once every such topic has delivered a later one — it is then
written in canonical order (no timing assumption). The bag is finished once the ``run_end`` event
and the final world state (same stamp) have arrived and nothing more came for ``drain_s``;
on SIGINT or SIGTERM (the bag is finished with everything received so far: summary and
``metadata.yaml``, exit status 130, no report); or after ``idle_timeout_s`` without any message.
The bag's chunks span at most 1 s of simulated time and each is handed to the OS when closed,
so even SIGKILL loses at most the last second recorded; ``scripts/reindex.py`` rebuilds the
summary and ``metadata.yaml`` of such a bag (see docs/recording.md). The per-step topics are
keep-all (see the contract), so a recorder lagging behind the simulation loses nothing.

Trusted sources (docs/wire.md): a message is recorded only if its publisher (GID, looked up once
in the graph) belongs to the node the contract names for its topic — ``evoscen_sim`` for the
world, events, clock, odometry, roster and markers; ``evoscen_bv``/``evoscen_sut`` for the
commands (with ``external_sut``: the first node other than evoscen's own that sends a SUT
command) — so a forged ``run_end`` or collision event never reaches the bag or the report. A
command message is recorded only if it is a table stamped at a step time of the run. Everything
refused is counted, logged (at most ``MAX_WARNINGS`` lines) and not recorded; no message ends
the node with a traceback.

Scoring: the world tables, events and map markers the node writes into the bag also go, in
the same order, into a :class:`~evoscen_eval.scoring.rundata.RunAccumulator`, which scores them as
they come (:mod:`evoscen_eval.scoring.streaming`: nothing of the run is kept, so a long run costs no
memory); when the run ends the node writes ``report.json``, ``report.md`` and the plots into ``report_dir``
(not for a run that ended ``aborted``: it is not scored)
(:mod:`evoscen_eval.scoring.report`) — the very numbers ``scripts/evaluate.py`` computes from the bag.
The SUT's exposures go out live as ``evoscen/exposure`` events from the simulation node (same
definitions, :mod:`evoscen_sim.danger.safety`).

Parameters: ``scenario.*``, ``bag_dir`` (required: a new or empty directory), ``report_dir``
[""; empty = no report], ``report_plots`` [true],
``external_sut`` [false] (the SUT is a user's node: the bag's metadata and the report say so
rather than name the configuration's ``sut.model``), ``nice`` [10] (CPU priority below the lockstep nodes), ``drain_s`` [0.5], ``idle_timeout_s`` [60], ``batch_s`` [0.005]:
after taking messages the node sleeps this long so that several steps' messages are taken
per wake-up (it is outside the lockstep loop; fewer wake-ups leave more CPU to the loop).
"""

from __future__ import annotations

import signal
import sys
import time
from dataclasses import dataclass

from evoscen_contract import graph
from evoscen_contract import topics as T
from evoscen_contract.cdr import TableEncoder, decode_table, events_count, is_run_end
from evoscen_contract.contract import EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_OK
from evoscen_record.ordered_bag import OrderedBag
from evoscen_record.recorder import BagRecorder
from evoscen_record.scenario_record import SCENARIO_KEY, SCENARIO_METADATA, scenario_metadata
from evoscen_sim.config.config_checks import flag, integer, number, text
from evoscen_sim.errors import HostFault
from evoscen_sim.nodes.node_params import own_parameters, run_node, scenario_from_node

from evoscen_eval.scoring.rundata import RunAccumulator

NODE_NAME = T.NODE_EVAL
# topics only the simulation node publishes, always as canonical CDR (evoscen_contract.cdr)
_CANONICAL_TOPICS = {T.CLOCK.name, T.WORLD.name, T.SUT_ODOM.name, T.ROSTER.name, T.MARKERS.name}
MAX_WARNINGS = 20
"""Refused messages logged (one line each); the rest are counted."""


@dataclass(frozen=True)
class EvalParams:
    """The recorder's own parameters (see the module docstring), validated by
    :func:`~evoscen_sim.nodes.node_params.own_parameters`; ``bag_dir`` is required."""

    bag_dir: str = text("")
    drain_s: float = number(0.5, 0.0)
    batch_s: float = number(0.005, 0.0)
    nice: int = integer(10, 0, 19)
    idle_timeout_s: float = number(60.0, 0.0, lo_open=True)
    report_dir: str = text("", allow_empty=True)
    report_plots: bool = flag(True)
    external_sut: bool = flag(False)


class EvaluatorNode:
    """The recorder (see the module docstring)."""

    def __init__(self) -> None:
        # SIGINT and SIGTERM finish the bag (checked between batches of messages, never in the
        # middle of a write); set first, so that a signal during start-up is not lost either
        self._stop_signal: int | None = None
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._on_signal)
        self.node = graph.make_node(NODE_NAME)
        params = graph.node_parameters(self.node)
        self.cfg = scenario_from_node(params, NODE_NAME)
        own = own_parameters(EvalParams, params, NODE_NAME)
        bag_dir = own.bag_dir
        self.drain_s = own.drain_s
        self.batch_s = own.batch_s
        self.nice = own.nice
        if self.nice:
            # outside the lockstep loop, and the topics are keep-all: lagging costs memory, never data,
            # so the recorder yields the CPU to the loop (measurable on a 2-core machine)
            import os

            os.nice(self.nice)
        self.idle_timeout_s = own.idle_timeout_s
        self.report_dir = own.report_dir
        self.report_plots = own.report_plots
        self.external_sut = own.external_sut
        self.metadata = scenario_metadata(self.cfg, external_sut=self.external_sut)  # the bag's; the report reads it too
        self.acc = None
        if self.report_dir:  # scored state by state (evoscen_eval.scoring.streaming): memory does not grow with the run
            import yaml

            from evoscen_eval.scoring.rundata import evaluation_settings_of

            recorded = yaml.safe_load(self.metadata[SCENARIO_KEY])  # as an offline evaluation reads it
            self.acc = RunAccumulator(keep_world=False)
            self.acc.start_scoring(evaluation_settings_of(recorded), float(recorded["dt_s"]))
        self.dt_ns = round(self.cfg.dt_s * 1e9)
        rec = self.cfg.recording
        from evoscen_record.reindex import finish_bag

        # one command topic per BV node of bvs.nodes, in the partition's order (docs/architecture.md
        # §5, "BV nodes"): the bag's channels and per-step order are the in-process runner's
        from evoscen_sim.nodes.bv_nodes import bv_node_names

        bv_names = bv_node_names(self.cfg)
        contract = T.contract_for(bv_names)
        bv_specs = [spec for spec in contract if T.is_bv_command_topic(spec.name)]
        self.table_topics = {T.COMMANDS_SUT.name, *(spec.name for spec in bv_specs)}
        self.bag = OrderedBag(BagRecorder(bag_dir, contract, compression=rec.compression,
                                          chunk_size=rec.chunk_size_bytes,
                                          metadata={SCENARIO_METADATA: self.metadata},
                                          finish_after_fault=finish_bag),
                              contract)
        if self.acc is not None:  # the scores see exactly what the bag gets, in the bag's order
            self.bag.on_write = self.acc.add_bytes
        self.subs = {spec.name: graph.subscription(self.node, spec, raw=True) for spec in contract}
        self.takers = {name: graph.SourceTaker(sub) for name, sub in self.subs.items()}
        trusted = {spec.name: [T.NODE_SIM] for spec in contract if spec.publisher == T.NODE_SIM}
        for spec in bv_specs:
            trusted[spec.name] = [spec.publisher]
        trusted[T.COMMANDS_SUT.name] = None if self.external_sut else [T.NODE_SUT]
        self.gate = graph.SourceGate(self.node, trusted, exclude=[T.NODE_SIM, T.NODE_BV, *bv_names, T.NODE_EVAL])
        self.refused = 0
        self.pump = graph.MessagePump(self.node, self.subs.values())
        self._encoders: dict = {}
        per_step = [T.CLOCK, T.WORLD, T.SUT_ODOM, T.EVENTS, T.COMMANDS_SUT] + (bv_specs if self.cfg.bvs.count else [])
        self.latest = {spec.name: -1 for spec in per_step}
        self.markers_every = self.cfg.recording.markers_every
        self.latest_markers = -self.markers_every * self.dt_ns  # the first markers are due at t = 0
        self.run_end_ns: int | None = None
        self.run_end_kind: str | None = None  # completed, aborted or interrupted

    def _on_signal(self, signum, frame) -> None:
        self._stop_signal = signum

    def _take_all(self) -> int:
        """Take every available message; returns how many."""
        taken = 0
        for topic, taker in self.takers.items():
            while (got := taker.take()) is not None:
                taken += 1
                data, gid = got
                if not self.gate.allows(topic, gid):
                    self._refuse(topic, gid, "not from the publisher the contract names")
                    continue
                try:
                    self._record(topic, data)
                except HostFault:  # the disk, not the message: ends the recording (run())
                    raise
                except Exception as exc:  # noqa: BLE001 - no message may end the recorder
                    self._refuse(topic, gid, f"unreadable ({exc!r:.200})")
        # every per-step topic has one message per step, each topic in order: all messages
        # before the oldest of the topics' latest stamps are in, so that much can be written
        complete = min(self.latest.values())
        if self.markers_every:  # vehicle markers come every markers_every steps: wait for the next one too
            due = self.latest_markers + self.markers_every * self.dt_ns
            if due <= self.cfg.steps * self.dt_ns:
                complete = min(complete, due)
        self.bag.flush_before(complete)
        return taken

    def _record(self, topic: str, data: bytes) -> None:
        """Queue one trusted message for the bag (ValueError & co. for bytes that do not parse)."""
        t_ns = _stamp_ns(topic, data)
        if t_ns < 0:
            raise ValueError(f"negative stamp {t_ns} ns")
        canonical = topic in _CANONICAL_TOPICS
        if topic == T.EVENTS.name and events_count(data) == 0:
            canonical = True  # a step without events: the simulation's canonical template
        if topic in self.table_topics:
            if t_ns >= self.cfg.steps * self.dt_ns or (self.run_end_ns is not None and t_ns >= self.run_end_ns):
                # an answer to the state the run ended at (the final state, or the step an abort or Ctrl-C
                # ended it at): the simulation never used it, so it is no answer to a step the run took
                return
            if t_ns % self.dt_ns:
                raise ValueError(f"stamp {t_ns} ns is not a step time")
            data, canonical = self._canonical_table(data), True
        run_end = topic == T.EVENTS.name and is_run_end(data)  # parses (raises) before anything is queued
        self.bag.add(topic, data, t_ns, canonical=canonical)
        if topic in self.latest:
            self.latest[topic] = max(self.latest[topic], t_ns)
        elif topic == T.MARKERS.name:
            self.latest_markers = max(self.latest_markers, t_ns)
        if run_end:
            self.run_end_ns = t_ns
            self.run_end_kind = _run_end_kind(data)
            # [choice] answers that arrived before run_end, to the step the run ended at, go too: a controller
            # killed right after publishing its answer to step K leaves it with the recorder while the
            # simulation, told of the death, aborts at K without it (the middleware hands a sample to each
            # reader in turn). Whatever the order of arrival, the bag's command tables are answers to
            # steps 0 .. K-1 only (docs/recording.md, "A controller that dies during a step"). They are
            # still queued: nothing at K is written before every per-step topic has a later message.
            self.bag.drop_pending(self.table_topics, t_ns)

    def _refuse(self, topic: str, gid: bytes | None, reason: str) -> None:
        self.refused += 1
        if self.refused <= MAX_WARNINGS:
            print(f"warning: {NODE_NAME}: {topic}: message from {self.gate.name_of(topic, gid)} not recorded: {reason}"
                  + (" (further ones are only counted)" if self.refused == MAX_WARNINGS else ""), file=sys.stderr)

    def _canonical_table(self, data: bytes) -> bytes:
        """A command table in canonical CDR (any publisher's encoding), via decode + re-encode."""
        t = decode_table(data)  # TableDecodeError (a ValueError): not recorded
        encoder = self._encoders.get((t.fields, t.frame_id))
        if encoder is None:
            encoder = self._encoders[(t.fields, t.frame_id)] = TableEncoder(t.fields, t.frame_id)
        return encoder.encode(t.data, t.stamp_ns)

    def _finished(self, last_message: float) -> bool:
        return (self.run_end_ns is not None and self.latest[T.WORLD.name] >= self.run_end_ns
                and time.monotonic() - last_message >= self.drain_s)

    def run(self) -> int:
        """Record until the run ends; returns the exit status."""
        status = EXIT_OK
        fault: HostFault | None = None
        last_message = time.monotonic()
        try:
            # until the run_end event and the final world state (same stamp) are in, and then
            # everything still in flight (drain_s without a message)
            while not self._finished(last_message):
                if self._stop_signal is not None:
                    raise KeyboardInterrupt
                if self._take_all():
                    last_message = time.monotonic()
                    time.sleep(self.batch_s)  # let a few steps accumulate: fewer wake-ups, less CPU
                elif time.monotonic() - last_message > self.idle_timeout_s:
                    print(f"error: {NODE_NAME}: no message for {self.idle_timeout_s:g} s; finishing the bag",
                          file=sys.stderr)
                    status = EXIT_FAULT
                    break
                self.pump.wait(0.02 if self.run_end_ns is not None else 0.1)
        except KeyboardInterrupt:
            status = EXIT_INTERRUPTED
        except HostFault as exc:  # a full disk, a read-only or removed output directory
            fault = exc
        finally:
            try:
                self.bag.close()  # after a fault: finished from what reached the disk, or cut back to it
            except HostFault as exc:
                fault = fault or exc
        if fault is not None:  # one line, once the bag's state is known; no report
            print(f"error: {fault.line()}", file=sys.stderr)  # the in-process runner's line
            return EXIT_HOST_FAULT
        if self.refused:
            print(f"warning: {NODE_NAME}: {self.refused} message(s) not recorded (untrusted or unreadable)",
                  file=sys.stderr)
        if status == EXIT_INTERRUPTED:
            name = signal.Signals(self._stop_signal or signal.SIGINT).name
            print(f"{NODE_NAME}: {name}: bag finished with {self.bag.message_count} messages", file=sys.stderr)
        if self.acc is not None and status != EXIT_INTERRUPTED and self.run_end_kind == T.KIND_ABORTED:
            # a run aborted (a controller fault: its driver raised, it died or missed its deadlines) is
            # not scored: a score of its first steps would pass for the run's (docs/recording.md)
            print(f"{NODE_NAME}: the run was aborted: bag finished with {self.bag.message_count} messages; "
                  "no report (an aborted run is not scored)", file=sys.stderr)
        elif self.acc is not None and status != EXIT_INTERRUPTED:
            status = self._write_report(status)
        return status

    def _write_report(self, status: int) -> int:
        """Score the run and write the report (a failure is reported, the bag is kept)."""
        import yaml
        from evoscen_sim.errors import InputError

        from evoscen_eval.scoring.report import write_stream_report

        try:
            info = self.acc.stream_info(scenario=yaml.safe_load(self.metadata[SCENARIO_KEY]),
                                        external_sut=self.external_sut)
            write_stream_report(self.acc.stream, info, [], self.report_dir, plots=self.report_plots,
                                lane_segments=self.acc.lane_segments)
        except (InputError, ValueError) as exc:
            print(f"error: {NODE_NAME}: no report: {exc}", file=sys.stderr)
            return status or EXIT_FAULT
        except (HostFault, OSError) as exc:  # the bag is finished; the report could not be written
            fault = exc if isinstance(exc, HostFault) else HostFault.of(exc, exc.filename or self.report_dir)
            fault.bag_dir, fault.bag_state = self.bag.bag.bag_dir, "finished"
            print(f"error: {fault.line()}", file=sys.stderr)  # the in-process runner's line
            return EXIT_HOST_FAULT
        return status


# where the stamp of each contract message starts: after the 4-byte CDR header comes a
# builtin_interfaces/Time (Clock.clock, Header.stamp), except for a MarkerArray: its
# sequence length, then the first marker's header (evoscen's marker arrays are never empty)
_STAMP_OFFSET = {T.MARKERS.name: 8, T.MAP_MARKERS.name: 8}


def _stamp_ns(topic: str, data: bytes) -> int:
    """The stamp (= log time) of a serialized contract message, in ns."""
    at = _STAMP_OFFSET.get(topic, 4)
    sec = int.from_bytes(data[at:at + 4], "little", signed=True)
    nanosec = int.from_bytes(data[at + 4:at + 8], "little")
    return sec * 1_000_000_000 + nanosec


def _run_end_kind(data: bytes) -> str | None:
    """The ``kind`` of the ``run_end`` event in serialized ``/evoscen/events`` bytes."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    for event in T.parse_events(deserialize_message(bytes(data), DiagnosticArray)):
        if event.get("name") == T.EVENT_RUN_END:
            return event.get("kind")
    return None


def main(args: list[str] | None = None) -> int:
    """Entry point: one-line errors for bad parameters (exit 2)."""
    return run_node(EvaluatorNode, args)


if __name__ == "__main__":
    sys.exit(main())
