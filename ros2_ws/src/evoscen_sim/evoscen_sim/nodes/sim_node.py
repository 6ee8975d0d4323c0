"""The simulation node: owns time and the world, steps in lockstep with its controllers.

    python -m evoscen_sim.nodes.sim_node --ros-args --params-file sim.yaml   (or: ros2 run evoscen_sim sim_node ...)

The steps are run by the step loop the in-process runner drives too
(:class:`evoscen_sim.loop.step_loop.StepLoop`); this node is the loop's port on the graph. Step k:
publish ``/clock``, ``/evoscen/world`` and ``/evoscen/sut/odom`` at t_k (and the
latched ``/evoscen/roster`` before the first step); wait until every registered controller
(``controllers``: the BV nodes, the SUT node) has answered with commands stamped t_k;
integrate to t_{k+1}; publish what happened on ``/evoscen/events`` (every step; an empty
array when nothing happened, so every per-step topic has one message per step and the
recorder knows when a step is complete). After the last step the
final state and a ``run_end`` event go out.

Start-up waits (``startup_timeout_s``) until every controller and the recorder are matched
on every topic, so no message is lost. A controller that misses the deadline of a step
(``deadline_s``) is a fault: its last throttle is held (no lane change), a ``fault`` event
(kind ``deadline``) is published, and after ``max_misses`` consecutive misses the run stops
cleanly: ``fault`` (kind ``abort``) and ``run_end`` (kind ``aborted``) events, a one-line
error naming the controller, exit status 3. Ctrl-C ends the run after the current step
(``run_end`` kind ``interrupted``, exit status 130). Never a hang.

Parameters: ``scenario.*`` (the scenario configuration, validated like the YAML file),
``deadline_s`` [2.0], ``startup_timeout_s`` [30.0], ``max_misses`` [5], ``controllers``
[``[]``: every BV node of ``bvs.nodes`` and ``evoscen_sut``], ``recorder`` [true]: wait for the evaluator node,
``external_sut`` [false]: the SUT's commands come from a user's node (any name),
``stats_file`` [""]: write the lockstep rate there (JSON), ``discovery_settle_s`` [0.5]: at
start-up, how long discovery must stay quiet (all endpoints matched) before step 0,
``wait_for_nodes`` [[]]: names of users' nodes (a monitor, a bridge) that must have
subscribed to an evoscen topic before step 0 — so they get every step.
``recorder_lag_steps`` [50]: flow control towards the recorder (and every other reader): every
this many steps, before publishing the next state, the node waits until every sample it has
published on the topics the controllers do not read (all but ``/evoscen/world``) is
acknowledged by all matched readers — however long that takes (a stalled recorder
holds the lockstep; the wait is not a controller deadline), checking Ctrl-C every 0.1 s. So no
writer's history (the simulation's or a controller's) ever holds more than about this many
unacknowledged samples, far below the middleware's resource limits (``fastdds_profiles.xml``):
before, a recorder stalled ~10 s filled a controller's history and its publish failed.
``ready_file`` [""]: a file created once start-up is over, just before step 0 (the launcher
reads it to tell a death during start-up from one during the lockstep).
``deaths_file`` [""]: a file in which the launcher names (one a line) the controllers whose
process ended during the lockstep; a step waiting for the answer of a controller named there is
aborted at once (``DEATH_CHECK_S`` after it began: no deadline waits; a ``fault`` event of kind
``abort``); an abort for a controller named there is the consequence of its end, which the
launcher or the controller reports (exit status 4 or 3): the node's abort line then goes without
the ``error:`` prefix and says so.
"""

from __future__ import annotations

import signal
import sys
import time
from dataclasses import dataclass

import numpy as np
from evoscen_contract import graph, wire
from evoscen_contract import topics as T
from evoscen_contract.contract import EXIT_FAULT, EXIT_INTERRUPTED, EXIT_OK
from evoscen_contract.messages import WorldMessages

from evoscen_sim.config.config_checks import flag, integer, names, number, text
from evoscen_sim.errors import InputError
from evoscen_sim.danger.events import fault_event, step_events
from evoscen_sim.loop.step_loop import Commands, Port, RunAborted, StepLoop
from evoscen_sim.scenario_builders import SUT_INDEX, build_world

from .node_params import own_parameters, run_node, scenario_from_node

NODE_NAME = T.NODE_SIM
LEAVE_ANNOUNCE_S = 0.05  # see SimulationNode._leave
DEATH_CHECK_S = 0.05
"""A step's commands outstanding this long: look in ``deaths_file`` for controllers whose process ended
(then the run is aborted at once; a normal step never waits this long, so it never reads the file)."""
DEAD_READER_WAIT_S = 0.2
"""After an abort for a controller whose process ended, how long the end waits for acknowledgements of
``/evoscen/world`` (the dead one, still matched, never acknowledges; the other topics, which the
recorder alone reads, are waited for first)."""
WIRE_EVENTS_PER_STEP = 4
"""At most this many wire ``fault`` events per step (distinct topic/publisher/reason; the rest are counted)."""
WIRE_EVENTS_PER_RUN = 200
"""At most this many wire ``fault`` events per run; the last one says that further ones are suppressed."""

EXIT_STATUS = {T.KIND_COMPLETED: EXIT_OK, T.KIND_ABORTED: EXIT_FAULT, T.KIND_INTERRUPTED: EXIT_INTERRUPTED}
"""The node's exit status for each way a run ends (``run_end`` kind)."""


@dataclass(frozen=True)
class SimParams:
    """The simulation node's own parameters (see the module docstring), validated by
    :func:`~evoscen_sim.nodes.node_params.own_parameters`."""

    deadline_s: float = number(2.0, 0.0, lo_open=True)
    startup_timeout_s: float = number(30.0, 0.0, lo_open=True)
    max_misses: int = integer(5, 1)
    controllers: tuple[str, ...] = names((), distinct=True)
    """[] (default): every BV node of the scenario's ``bvs.nodes`` and the SUT node."""
    recorder: bool = flag(True)
    stats_file: str = text("", allow_empty=True)
    external_sut: bool = flag(False)
    wait_for_nodes: tuple[str, ...] = names(())
    discovery_settle_s: float = number(0.5, 0.0)
    recorder_lag_steps: int = integer(50, 0)
    ready_file: str = text("", allow_empty=True)
    deaths_file: str = text("", allow_empty=True)


class SimulationNode(Port):
    """The simulation node (see the module docstring): the graph's port of the step loop.

    :class:`~evoscen_sim.loop.step_loop.StepLoop` runs the steps; this node waits for the graph
    at start-up (:meth:`start`), keeps flow control towards the recorder (:meth:`begin_step`),
    publishes the states and events on the contract's topics and collects the controllers'
    commands with deadlines (:meth:`commands`: held throttles, wire and deadline faults,
    aborts).
    """

    def __init__(self) -> None:
        self.node = graph.make_node(NODE_NAME)
        params = graph.node_parameters(self.node)
        self.cfg = scenario_from_node(params, NODE_NAME)
        own = own_parameters(SimParams, params, NODE_NAME)
        self.deadline_s = own.deadline_s
        self.startup_timeout_s = own.startup_timeout_s
        self.max_misses = own.max_misses
        self.controllers = list(own.controllers)
        self.recorder = own.recorder
        self.stats_file = own.stats_file
        self.external_sut = own.external_sut
        self.wait_for_nodes = list(own.wait_for_nodes)
        self.discovery_settle_s = own.discovery_settle_s
        self.recorder_lag_steps = own.recorder_lag_steps
        self.flow_waits, self.flow_wait_s = 0, 0.0  # flow control's waits for acknowledgements (stats_file)
        self.ready_file = own.ready_file
        self.deaths_file = own.deaths_file
        self.aborted_by: str | None = None  # the controller whose misses aborted the run

        # the controllers and their command topics: one per BV node of bvs.nodes and the SUT
        # (docs/architecture.md §5, "BV nodes")
        from .bv_nodes import bv_nodes

        bvs = bv_nodes(self.cfg)
        self.controller_topics = {**{b.name: T.bv_command_spec(b.name) for b in bvs}, T.NODE_SUT: T.COMMANDS_SUT}
        self.controller_rows = {b.name: b.rows for b in bvs}
        self.controller_rows[T.NODE_SUT] = np.array([SUT_INDEX])
        if not self.controllers:
            self.controllers = list(self.controller_topics)
        unknown = [c for c in self.controllers if c not in self.controller_topics]
        if unknown:
            raise InputError(f"{NODE_NAME}: key 'controllers' = {list(self.controllers)}: expected names from "
                             f"{', '.join(self.controller_topics)} (the scenario's BV nodes, bvs.nodes = "
                             f"{self.cfg.bvs.nodes}, and the SUT node)")
        self.world = build_world(self.cfg)
        self.loop = StepLoop(self.world, self.cfg.evaluation, self, interrupted_text="run interrupted (SIGINT)")
        self.msgs = WorldMessages(self.cfg.dt_s)
        n = self.node
        self.pub = {spec.name: graph.publisher(n, spec)
                    for spec in (T.CLOCK, T.WORLD, T.SUT_ODOM, T.EVENTS, T.ROSTER, T.MARKERS, T.MAP_MARKERS)}
        self.subs = {c: graph.subscription(n, self.controller_topics[c], raw=True) for c in self.controllers}
        self.takers = {c: graph.SourceTaker(sub) for c, sub in self.subs.items()}
        self.pump = graph.MessagePump(n, self.subs.values())
        ids = self.world.columns()["id"]
        self.expected_ids = {c: np.array(ids[self._rows_of(c)], dtype=np.float64) for c in self.controllers}
        self.sources: dict[str, dict[bytes, str]] = {}  # per controller: registered publisher GID -> node name
        self._wire_faults: dict[tuple[str, str, str, str], int] = {}  # this step's: (controller, topic, publisher, reason) -> messages
        self._wire_events = 0
        self._wire_logged: set = set()
        self._foreign_names: dict = {}  # (topic, GID) -> node name (None: not in the graph)
        self._warm_up()  # while discovery runs in the middleware's threads
        # commands held for a controller that misses a deadline: its last throttle, no lane change
        self.throttle = np.zeros(self.world.n)
        self.lane_change = np.zeros(self.world.n, dtype=np.int64)
        self.misses = dict.fromkeys(self.controllers, 0)
        self._cols = None  # the columns of the state being published
        # Ctrl-C / SIGTERM take effect at step boundaries (never between two publications of a step)
        self._interrupted = False
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._on_signal)

    def _warm_up(self) -> None:
        """Run one step's kernels on a copy of the world, so that step 0 is not the slow one.

        The compiled kernels are loaded from numba's cache on first use (about a second on the
        2-core VM); without this, that second falls into the first lockstep step, where the
        controllers wait for it. The copy leaves the world (its random stream included) and
        the exposure monitor as they were.
        """
        import copy

        world = copy.deepcopy(self.world)
        result = world.step(np.zeros(world.n), np.zeros(world.n, dtype=np.int64))
        step_events(world, result)
        copy.deepcopy(self.loop.exposures).observe(world)
        type(self.msgs)(self.cfg.dt_s).vehicle_markers(world.columns(), world.time_ns)  # a spare encoder

    def _on_signal(self, signum, frame) -> None:
        self._interrupted = True

    def _check_interrupt(self) -> None:
        if self._interrupted:
            raise KeyboardInterrupt

    # ------------------------------------------------------------------ publishing
    def _publish(self, spec: T.TopicSpec, data: bytes) -> None:
        self.pub[spec.name].publish(data)

    def send_world(self, world, *, roster: bool) -> None:
        """The world at t_k first: what the controllers wait for.

        The rest — the events of the step that led to t_k (worked out by the loop only now,
        while the controllers compute), ``/clock``, odometry, markers (:meth:`send_state`) —
        is off the critical path. The bag's order does not depend on the publishing order:
        the recorder writes each step in canonical order.
        """
        m, t_ns = self.msgs, world.time_ns
        self._cols = cols = world.columns()
        self._publish(T.WORLD, m.world(cols, t_ns))
        if roster:
            self._publish(T.ROSTER, m.roster(cols, t_ns))
            self._publish(T.MAP_MARKERS, m.map_markers(world.road, t_ns))

    def send_events(self, events: list[dict], t_ns: int) -> None:
        self._publish(T.EVENTS, self.msgs.events(events, t_ns))

    def send_state(self, world) -> None:
        m, t_ns, cols = self.msgs, world.time_ns, self._cols
        self._cols = None
        self._publish(T.CLOCK, m.clock(t_ns))
        self._publish(T.SUT_ODOM, m.odometry(cols, SUT_INDEX, t_ns))
        every = self.cfg.recording.markers_every
        if every and world.step_index % every == 0:
            self._publish(T.MARKERS, m.vehicle_markers(cols, t_ns))

    # ------------------------------------------------------------------ start-up
    def _unmatched(self) -> list[str]:
        """What start-up still waits for (empty when every peer is matched on every topic)."""
        ours = [c for c in self.controllers if not (c == T.NODE_SUT and self.external_sut)]
        recorder = [T.NODE_EVAL] if self.recorder else []
        missing = []
        for name, pub in self.pub.items():
            required = recorder + (ours if name == T.WORLD.name else [])
            at_least = len(required) + (1 if name == T.WORLD.name and self.external_sut else 0)
            why = graph.peers_missing(self.node, name, "subscribers", pub.get_subscription_count(), required,
                                      at_least=at_least) if at_least else None
            if why:
                missing.append(why)
        if self.wait_for_nodes:  # users' nodes asked for: each subscribed to one of our topics at least
            subscribed = {info.node_name for name in self.pub for info in self.node.get_subscriptions_info_by_topic(name)}
            missing += [f"{name}: waiting for this node (wait_for_nodes) to subscribe to an evoscen topic"
                        for name in self.wait_for_nodes if name not in subscribed]
        for c, sub in self.subs.items():
            required = [] if (c == T.NODE_SUT and self.external_sut) else [c]
            why = graph.peers_missing(self.node, sub.topic_name, "publishers", sub.get_publisher_count(), required)
            if why:
                missing.append(why)
        return missing

    def wait_for_graph(self) -> None:
        """Block until every peer is matched; RunAborted after ``startup_timeout_s``.

        Every discovered endpoint must be matched and discovery must have been quiet for
        ``discovery_settle_s``, so a user's node that is already running when the run starts
        (a monitor, Foxglove bridge) gets the first step too. Also refuses a domain where
        another simulation node already publishes the world: two graphs on one ROS_DOMAIN_ID
        would take each other's commands and record each other.
        """
        deadline = time.monotonic() + self.startup_timeout_s
        settled_since, last_seen = None, None
        while True:
            missing = self._unmatched()
            seen = self._discovered()
            now = time.monotonic()
            if missing:
                settled_since, last_seen = None, seen
            elif settled_since is None or seen != last_seen:
                settled_since, last_seen = now, seen  # all matched: now discovery must stay quiet
            elif now - settled_since >= self.discovery_settle_s:
                self._register_sources()
                return
            self._check_alone()
            self._check_interrupt()
            if now > deadline:
                why = "; ".join(missing) or "discovery did not settle"
                raise RunAborted(f"start-up: not matched after {self.startup_timeout_s:g} s: {why}")
            time.sleep(0.02)

    def _register_sources(self) -> None:
        """Pin each controller's command publishers (GIDs) as the graph shows them now.

        A controller's publishers are the endpoints on its command topic of the node named like
        it (``evoscen_bv``, ``evoscen_sut``); with ``external_sut``, every publisher of the SUT's
        command topic present at start-up (the user's node may have any name). Any other
        publisher is foreign for the whole run (see docs/wire.md).
        """
        for c in self.controllers:
            topic = self.controller_topics[c].name
            anyone = c == T.NODE_SUT and self.external_sut
            self.sources[c] = {gid: name for gid, name in graph.publisher_names(self.node, topic).items()
                               if anyone or name == c}
        if not all(t.per_message for t in self.takers.values()):
            self.node.get_logger().warning(f"no per-message publisher GIDs ({self.takers[self.controllers[0]].why_not}): "
                                           "foreign command publishers are only counted")

    def _discovered(self) -> tuple:
        """Every endpoint discovered on our topics (to see discovery settle)."""
        n = self.node
        return tuple(sorted((name, len(n.get_subscriptions_info_by_topic(name)), len(n.get_publishers_info_by_topic(name)))
                            for name in [*self.pub, *(s.topic_name for s in self.subs.values())]))

    # ------------------------------------------------------------------ lockstep
    def start(self) -> None:
        """Start-up: wait for the graph, then create ``ready_file``."""
        self.wait_for_graph()
        if self.ready_file:
            with open(self.ready_file, "w", encoding="utf-8"):
                pass

    def begin_step(self, step: int) -> None:
        """Ctrl-C takes effect here; flow control every ``recorder_lag_steps`` steps."""
        self._check_interrupt()
        lag = self.recorder_lag_steps
        if lag and step and step % lag == 0:
            self._wait_acked()

    def commands(self, step: int) -> Commands:
        """The controllers' commands for ``step`` (the first step waits up to ``startup_timeout_s``)."""
        return self._collect_commands(step, self.startup_timeout_s if step == 0 else self.deadline_s)

    def _collect_commands(self, step: int, timeout_s: float) -> Commands:
        """Take the commands stamped for this step from every controller (or count a miss).

        A message counts only if it comes from the controller's registered publisher and
        :func:`evoscen_contract.wire.check_commands` finds it well formed. The first message of
        the registered publisher stamped ``t_k`` decides the step: well formed, it is applied;
        malformed, the controller's vehicles hold their last throttle (no lane change), as on a
        missed deadline. Everything else — foreign publishers, wrong stamps, garbage — is
        ignored for control and reported as a ``fault`` event (kind ``wire``).

        The fault events come back with the commands, one ``/evoscen/events`` message per
        list, in the order found; after ``max_misses`` misses in a row, with ``abort`` set.
        """
        t_ns = self.world.time_ns
        pending = set(self.controllers)
        malformed: set[str] = set()
        events: list[list[dict]] = []
        start = time.monotonic()
        deadline = start + timeout_s
        while True:
            for c in self.controllers:
                taker, topic = self.takers[c], self.controller_topics[c].name
                while (got := taker.take()) is not None:
                    data, gid = got
                    self._one_command(c, topic, data, gid, t_ns, pending, malformed)
            remaining = deadline - time.monotonic()
            if not pending or remaining <= 0:
                break
            self._check_interrupt()
            if self.deaths_file and time.monotonic() - start >= DEATH_CHECK_S:
                dead = [c for c in self.controllers if c in pending and c in self._ended()]
                if dead:  # its process ended (the launcher named it): no answer will come
                    return self._abort_for_death(dead[0], step, events)
            self.pump.wait(min(remaining, 0.1))
        order = self.controllers
        if any(self.misses[c] + 1 >= self.max_misses for c in pending | malformed):
            # an abort at this step: a controller whose process ended (deaths_file) is its cause, also
            # when a live one reaches its last miss at the same step (a loaded machine): named first
            dead = [c for c in order if c in pending and self._died(c)]
            order = dead + [c for c in order if c not in dead]
        for c in order:
            if c not in pending and c not in malformed:
                self.misses[c] = 0
                continue
            self.misses[c] += 1
            rows = self._rows_of(c)
            self.lane_change[rows] = 0
            kind = T.KIND_ABORT if self.misses[c] >= self.max_misses else T.KIND_DEADLINE
            what = (f"sent malformed commands or missed deadlines {self.misses[c]} consecutive times"
                    if c in malformed else f"missed {self.misses[c]} consecutive deadline(s) of {timeout_s:g} s")
            text = (f"controller '{c}' {what} at step {step}"
                    + ("; run aborted" if kind == T.KIND_ABORT else "; holding its last throttle"))
            if c in malformed and kind == T.KIND_DEADLINE:
                continue  # its wire fault event says it; the throttle is held
            self._flush_wire_faults(events)
            events.append([fault_event(self.world, kind, c, self.misses[c], text)])
            self.node.get_logger().warning(text)
            if kind == T.KIND_ABORT:
                self.aborted_by = c
                return Commands(self.throttle, self.lane_change, events, abort=text)
        self._flush_wire_faults(events)
        return Commands(self.throttle, self.lane_change, events)

    def _abort_for_death(self, c: str, step: int, events: list[list[dict]]) -> Commands:
        """Abort the run at ``step``: controller ``c``'s process ended (``deaths_file``) before it answered."""
        self.misses[c] += 1
        text = f"controller '{c}' ended before answering step {step}; run aborted"
        self._flush_wire_faults(events)
        events.append([fault_event(self.world, T.KIND_ABORT, c, self.misses[c], text)])
        self.node.get_logger().warning(text)
        self.aborted_by = c
        return Commands(self.throttle, self.lane_change, events, abort=text)

    def _one_command(self, c: str, topic: str, data: bytes, gid: bytes | None, t_ns: int,
                     pending: set, malformed: set) -> None:
        """Apply or refuse one message of controller ``c``'s topic (see :meth:`_collect_commands`)."""
        sources = self.sources.get(c, {})
        if gid is not None and gid not in sources:
            self._wire_fault(c, topic, gid, f"not from a registered publisher of {c}")
            return
        if gid is None and self.subs[c].get_publisher_count() > len(sources):
            self._wire_fault(c, topic, gid, f"{self.subs[c].get_publisher_count()} publishers on the topic, "
                                            f"{len(sources)} registered (no per-message GIDs)")
        check = wire.check_commands(data, t_ns, self.expected_ids[c])
        if check.status == wire.STALE:
            return  # a late answer to an earlier step (after a missed deadline)
        at_step = check.table is not None and check.table.stamp_ns == t_ns
        if c not in pending and at_step:
            self._wire_fault(c, topic, gid, f"a second message for the step at {t_ns} ns")
            return
        if check.status == wire.BAD:
            self._wire_fault(c, topic, gid, check.reason)
            if at_step:
                pending.discard(c)
                malformed.add(c)
            return
        table = check.table.data
        rows = table[:, 0].astype(np.int64)  # ids are world indices
        self.throttle[rows] = table[:, 1]
        self.lane_change[rows] = table[:, 2].astype(np.int64)
        pending.discard(c)

    def _wire_fault(self, c: str, topic: str, gid: bytes | None, reason: str) -> None:
        name = self.sources.get(c, {}).get(gid) if gid is not None else None
        if gid is not None and name is None:
            if (topic, gid) not in self._foreign_names and len(self._foreign_names) < 1000:
                self._foreign_names[(topic, gid)] = graph.publisher_names(self.node, topic).get(gid)
            name = self._foreign_names.get((topic, gid))
        publisher = graph.gid_text(gid) + (f" (node '{name}')" if name and name != graph.UNKNOWN_NODE else "")
        key = (c, topic, publisher, reason)
        self._wire_faults[key] = self._wire_faults.get(key, 0) + 1
        if key not in self._wire_logged and len(self._wire_logged) < 1000:
            self._wire_logged.add(key)
            self.node.get_logger().warning(f"{topic}: message from {publisher} refused: {reason}")

    def _flush_wire_faults(self, out: list[list[dict]]) -> None:
        """This step's wire faults as ``fault`` events (rate-limited: WIRE_EVENTS_PER_STEP/PER_RUN).

        The events, if any, are appended to ``out`` as one ``/evoscen/events`` message.
        """
        if not self._wire_faults:
            return
        faults, self._wire_faults = list(self._wire_faults.items()), {}
        events = []
        for k, ((c, topic, publisher, reason), count) in enumerate(faults):
            if self._wire_events >= WIRE_EVENTS_PER_RUN:
                break
            last_of_run = self._wire_events == WIRE_EVENTS_PER_RUN - 1
            if k == WIRE_EVENTS_PER_STEP - 1 and len(faults) > WIRE_EVENTS_PER_STEP or last_of_run:
                rest = sum(n for _, n in faults[k:])
                why = "per step" if not last_of_run else "per run; no more wire fault events in this run"
                text = (f"{rest} refused message(s) from {len(faults) - k} topic/publisher/reason(s), "
                        f"events capped at {WIRE_EVENTS_PER_STEP if not last_of_run else WIRE_EVENTS_PER_RUN} {why}")
                ev = fault_event(self.world, "wire", c, self.misses.get(c, 0), f"{topic}: {text}")
                ev.update(topic=topic, publisher=publisher, reason=text, messages=rest)
                events.append(ev)
                self._wire_events += 1
                break
            ev = fault_event(self.world, "wire", c, self.misses.get(c, 0),
                             f"{topic}: {count} message(s) from {publisher} refused: {reason}")
            ev.update(topic=topic, publisher=publisher, reason=reason, messages=count)
            events.append(ev)
            self._wire_events += 1
        if events:
            out.append(events)

    def _wait_acked(self) -> None:
        """Flow control: until every matched reader has acknowledged every sample published.

        Not on ``/evoscen/world``: the controllers read it, and a dead controller (matched until
        its lease runs out, 20 s) would hold this wait instead of missing its deadlines. The
        recorder reads every topic and takes them together, so the per-step topics it alone
        reads (clock, odometry, events) bound its lag just as well.
        """
        t0 = time.perf_counter()
        for name, pub in self.pub.items():
            if name == T.WORLD.name:
                continue
            while not pub.wait_for_all_acked(graph.duration(0.1)):
                self._check_interrupt()
        self.flow_waits += 1
        self.flow_wait_s += time.perf_counter() - t0

    def _check_alone(self) -> None:
        others = self.node.count_publishers(T.WORLD.name) - 1
        if others > 0:
            domain = self.node.context.get_domain_id()
            raise RunAborted(f"start-up: ROS_DOMAIN_ID {domain} already has {others} other publisher(s) of "
                             f"{T.WORLD.name} (another evoscen graph or a replay); choose another domain")

    def _rows_of(self, controller: str) -> np.ndarray:
        return self.controller_rows[controller]

    def run(self) -> int:
        """The whole run (:class:`~evoscen_sim.loop.step_loop.StepLoop` with this port); returns the exit status."""
        outcome = self.loop.run(self.cfg.steps)
        if outcome.kind == T.KIND_ABORTED and self._died(self.aborted_by):
            print(f"{NODE_NAME}: {outcome.text} (its process had ended: the launcher names it)", file=sys.stderr)
        elif outcome.kind == T.KIND_ABORTED:
            print(f"error: {NODE_NAME}: {outcome.text}", file=sys.stderr)
        if outcome.wall_s is not None:  # start-up was over
            self._report(outcome.steps, outcome.wall_s)
        end = time.monotonic() + 1.0  # a dead reader would hold this for the whole timeout: 1 s in all
        dead = self._died(self.aborted_by)  # a controller whose process ended: a world reader that never acks
        for name in sorted(self.pub, key=lambda n: n == T.WORLD.name):  # the world last: the recorder's topics first
            wait_s = max(end - time.monotonic(), 0.0)
            if dead and name == T.WORLD.name:  # the recorder acknowledged what followed the final world state
                wait_s = min(wait_s, DEAD_READER_WAIT_S)
            self.pub[name].wait_for_all_acked(graph.duration(wait_s))
        self._leave()
        return EXIT_STATUS[outcome.kind]

    def _died(self, controller: str | None) -> bool:
        """Whether the launcher named ``controller`` in ``deaths_file`` (its process ended)."""
        return controller is not None and controller in self._ended()

    def _ended(self) -> set[str]:
        """The controllers the launcher named in ``deaths_file`` (their processes ended)."""
        if not self.deaths_file:
            return set()
        try:
            with open(self.deaths_file, encoding="utf-8") as f:
                return set(f.read().split())
        except OSError:  # none written (no controller died), or unreadable
            return set()

    def _leave(self) -> None:
        """Withdraw our publishers, so that peers see us gone at once.

        The process then ends without middleware teardown (:func:`evoscen_contract.graph.exit_now`),
        which the peers would only notice when our participant's lease runs out (20 s in Fast
        DDS). Destroying a publisher announces its removal now: the controllers of an aborted or
        interrupted run, which end when ``/evoscen/world`` has no publisher, stop within a
        fraction of a second instead of 20 s later.
        """
        for pub in self.pub.values():
            self.node.destroy_publisher(pub)
        self.pub = {}
        time.sleep(LEAVE_ANNOUNCE_S)  # a margin for the announcement to leave before the process ends

    def _report(self, steps: int, seconds: float) -> None:
        """Lockstep rate to stderr and, if asked, to ``stats_file`` (never into the bag: wall time)."""
        rate = steps / seconds if seconds > 0 else float("inf")
        print(f"{NODE_NAME}: lockstep: {steps} steps in {seconds:.2f} s ({rate:.0f} steps/s)", file=sys.stderr)
        if self.stats_file:
            import json

            with open(self.stats_file, "w", encoding="utf-8") as f:
                json.dump({"steps": steps, "loop_wall_s": seconds, "steps_per_s": rate,
                           "flow_control_waits": self.flow_waits, "flow_control_wait_s": self.flow_wait_s}, f)


def main(args: list[str] | None = None) -> int:
    """Entry point: run the node; one-line errors for bad parameters (exit 2)."""
    return run_node(SimulationNode, args)


if __name__ == "__main__":
    sys.exit(main())
