"""A controller node: answers every world message with commands for the vehicles it drives.

The BV node (:mod:`evoscen_bv.bv_node`) and the SUT node (:mod:`evoscen_sut.sut_node`) are
this loop with a different driver: take ``/evoscen/world`` at t_k, rebuild a
:class:`~evoscen_sim.loop.view.WorldView`, ask the driver, publish one command table stamped
t_k. Before answering the first world message the node waits until its command publisher
is matched with the simulation node and the recorder (``command_subscribers``: their node
names, default ``[evoscen_sim, evoscen_eval]``), so no command is lost.

It ends when the run does: on the final state of a completed run (the world stamped
``steps`` · dt, which asks for no answer), or — an aborted or interrupted run — when the
simulation node has left the graph (no publisher of ``/evoscen/world`` any more, checked
only after ``END_CHECK_S`` without a world message); on Ctrl-C; or after ``idle_timeout_s``
without a world message (the simulation node is gone without leaving the graph: killed).
A world message counts only if it comes from the simulation node's publisher (its GID, looked
up once, must belong to the node ``evoscen_sim``) and is a well-formed world table
(:func:`evoscen_contract.wire.check_world`: the world's columns and row count, a stamp on the step
grid); anything else is ignored with a warning (at most ``MAX_WARNINGS``), never answered and never
fatal (docs/wire.md).
[choice] Controllers do not subscribe to ``/evoscen/events`` for its ``run_end`` event:
that topic goes out every step, and its delivery woke both controllers a second time per
step, on the lockstep's critical path (the lockstep ran 763/989/1025 steps/s with it,
1018/1037/1237 without, interleaved pairs).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from evoscen_contract import graph, wire
from evoscen_contract import topics as T
from evoscen_contract.cdr import decode_table
from evoscen_contract.contract import EXIT_BAD_INPUT, EXIT_FAULT, EXIT_INTERRUPTED, EXIT_OK
from evoscen_contract.messages import WorldMessages

from evoscen_sim.config.config_checks import names, number
from evoscen_sim.errors import InputError, PluginFault
from evoscen_sim.model_registry import checked_answer, driver_identity, plugin_failure
from evoscen_sim.loop.view import WorldView
from evoscen_sim.road.road_model import load_road

from .node_params import own_parameters, run_node, scenario_from_node

MAX_WARNINGS = 20
"""Refused world messages logged (one line each); the rest are counted silently."""
END_CHECK_S = 0.1
"""Seconds without a world message after which a controller asks whether the simulation node left."""


@dataclass(frozen=True)
class ControllerParams:
    """A controller node's own parameters (see the module docstring), validated by
    :func:`~evoscen_sim.nodes.node_params.own_parameters`; a node's ``build`` may read more."""

    command_subscribers: tuple[str, ...] = names((T.NODE_SIM, T.NODE_EVAL))
    startup_timeout_s: float = number(30.0, 0.0, lo_open=True)
    idle_timeout_s: float = number(60.0, 0.0, lo_open=True)
    wait_for_nodes: tuple[str, ...] = names(())
    discovery_settle_s: float = number(0.5, 0.0)


class ControllerNode:
    """One controller (see the module docstring).

    Args:
        name: node name (``evoscen_bv``, ``evoscen_sut``); a name given on the command line
            (``--ros-args -r __node:=evoscen_bv_mutual``) replaces it: a BV node of ``bvs.nodes``
            is the same program under the name of its share (docs/architecture.md §5, "BV nodes").
        command_spec: the contract topic it publishes, or ``command_spec(cfg, name)`` giving it
            (raises InputError for a name the scenario has no controller of).
        build: ``build(params, cfg, name) -> (driver, vehicle indices)`` from the node's parameters,
            the validated scenario configuration and the node's name.
    """

    def __init__(self, name: str, command_spec: T.TopicSpec | Callable, build: Callable) -> None:
        self.node = graph.make_node(name)
        self.name = name = self.node.get_name()
        params = graph.node_parameters(self.node)
        self.cfg = scenario_from_node(params, name)
        if not isinstance(command_spec, T.TopicSpec):
            command_spec = command_spec(self.cfg, name)
        own = own_parameters(ControllerParams, params, name)
        self.command_subscribers = list(own.command_subscribers)
        self.startup_timeout_s = own.startup_timeout_s
        self.idle_timeout_s = own.idle_timeout_s
        self.wait_for_nodes = list(own.wait_for_nodes)
        self.discovery_settle_s = own.discovery_settle_s
        self._first_seen: dict[str, float] = {}
        try:
            self._build(build, params, name, command_spec)
        except PluginFault as exc:  # one line naming this node (run_node prints it; exit status 3)
            raise PluginFault(f"{name}: {exc}", model=exc.model, role=exc.role, step=exc.step) from None

    def _build(self, build: Callable, params, name: str, command_spec: T.TopicSpec) -> None:
        """The driver, the subscriptions and publisher, the warm-up (:meth:`__init__`)."""
        self.driver, self.vehicles = build(params, self.cfg, name)
        self._build_args = (params, name)
        self.road = load_road(self.cfg.map)
        self.msgs = WorldMessages(self.cfg.dt_s)
        self.dt_ns = round(self.cfg.dt_s * 1e9)
        self.world_sub = graph.subscription(self.node, T.WORLD, raw=True)
        self.world_taker = graph.SourceTaker(self.world_sub)
        self.gate = graph.SourceGate(self.node, {T.WORLD.name: [T.NODE_SIM]})
        self.refused = 0
        self.pub = graph.publisher(self.node, command_spec)
        self.pump = graph.MessagePump(self.node, [self.world_sub])
        self.final_ns = self.cfg.steps * self.dt_ns  # the final state of a completed run
        self._warm_up(build)  # while discovery runs in the middleware's threads

    def _warm_up(self, build: Callable) -> None:
        """Answer the initial world once with a spare driver, so that step 0 is not the slow one.

        The compiled kernels (road look-up, neighbourhood, the driver's own) are loaded from
        numba's cache on first use, a few hundred ms on the 2-core VM that would otherwise
        fall into the first lockstep step. The spare driver is built like the real one and
        thrown away: the real one (its random stream included) is untouched.
        """
        from evoscen_sim.scenario_builders import build_world

        world = build_world(self.cfg)
        self.n_vehicles = world.n
        params, name = self._build_args
        spare, _ = build(params, self.cfg, name)
        table = decode_table(self.msgs.world(world.columns(), world.time_ns))
        throttle, lane_change = checked_answer(spare, self._act(spare, WorldView(self.road, table.columns(), 0, self.cfg.dt_s)))
        WorldMessages(self.cfg.dt_s).commands(table.data[self.vehicles, 0], np.asarray(throttle, float),
                                              np.asarray(lane_change, float), 0)

    def _ready(self) -> bool:
        """Every required subscriber (by node name) has an endpoint on our topic, all matched.

        A node of ``wait_for_nodes`` (a user's monitor) must also have been discovered for
        ``discovery_settle_s``, so that its subscriptions, if it has any on our topic, are
        matched before the first command.
        """
        now = time.monotonic()
        if self.wait_for_nodes:
            known = set(self.node.get_node_names())
            for name in self.wait_for_nodes:
                if name in known:
                    self._first_seen.setdefault(name, now)
            if any(now - self._first_seen.get(name, now) < self.discovery_settle_s or name not in self._first_seen
                   for name in self.wait_for_nodes):
                return False
        return graph.peers_missing(self.node, self.pub.topic_name, "subscribers", self.pub.get_subscription_count(),
                                   self.command_subscribers, at_least=len(self.command_subscribers)) is None

    def _accept(self, data: bytes, gid: bytes | None) -> wire.Check | None:
        """The world table if the message is the simulation node's and well formed, else None."""
        topic = T.WORLD.name
        if not self.gate.allows(topic, gid):
            reason = "not from the simulation node's publisher"
        else:
            check = wire.check_world(data, T.WORLD_FIELDS, self.n_vehicles, self.dt_ns, self.final_ns)
            if check.status == wire.OK:
                return check
            reason = check.reason
        self.refused += 1
        if self.refused <= MAX_WARNINGS:
            print(f"warning: {self.name}: {topic}: message from {self.gate.name_of(topic, gid)} ignored: {reason}"
                  + (" (further ones are not logged)" if self.refused == MAX_WARNINGS else ""), file=sys.stderr)
        return None

    def answer(self, data: bytes, gid: bytes | None = None) -> bool:
        """Publish the commands answering one serialized world message; False for the final state
        of a completed run (no answer: the run is over). A refused message is not answered (True)."""
        check = self._accept(data, gid)
        if check is None:
            return True
        table = check.table
        t_ns = table.stamp_ns
        if t_ns >= self.final_ns:
            return False
        view = WorldView(self.road, table.columns(), t_ns // self.dt_ns, self.cfg.dt_s)
        throttle, lane_change = checked_answer(self.driver, self._act(self.driver, view))
        ids = view.ids[self.vehicles]
        self.pub.publish(self.msgs.commands(ids, np.asarray(throttle, float), np.asarray(lane_change, float), t_ns))
        return True

    def _act(self, driver, view):
        """``driver.act(view)``; an exception is a :class:`PluginFault` naming the model (one line)."""
        try:
            return driver.act(view)
        except Exception as exc:  # a model's failure is named in one line, not a traceback
            default = ("sut", self.cfg.sut.model) if self.name == T.NODE_SUT else ("bv", self.cfg.bvs.driver)
            name, role = driver_identity(driver, (default[1], default[0]))
            step = int(view.step_index)
            raise plugin_failure(exc, name, role, f"act() at step {step}", driver, step=step) from exc

    def _finish(self) -> int:
        """The run is over: our last commands acknowledged (bounded wait), exit status 0."""
        self.pub.wait_for_all_acked(graph.duration(2.0))
        return EXIT_OK

    def run(self) -> int:
        """Answer world messages until the run ends; returns the exit status."""
        started = time.monotonic()
        last_world = started
        ready = False  # checked (a graph query) until true, then never again: the hot loop stays cheap
        seen_world = False
        try:
            while True:
                if ready or (ready := self._ready()):
                    while (got := self.world_taker.take()) is not None:
                        seen_world, last_world = True, time.monotonic()
                        if not self.answer(*got):
                            return self._finish()
                elif time.monotonic() - started > self.startup_timeout_s:
                    print(f"error: {self.name}: start-up: {self.pub.topic_name} not matched with "
                          f"{', '.join(self.command_subscribers)} after {self.startup_timeout_s:g} s", file=sys.stderr)
                    return EXIT_FAULT
                idle = time.monotonic() - last_world
                if seen_world and idle > END_CHECK_S and self.world_sub.get_publisher_count() == 0:
                    return self._finish()  # the simulation node ended the run (aborted, interrupted) and left
                if idle > self.idle_timeout_s:
                    print(f"error: {self.name}: no world message for {self.idle_timeout_s:g} s; "
                          "the simulation node is gone", file=sys.stderr)
                    return EXIT_FAULT
                self.pump.wait(0.1)
        except KeyboardInterrupt:
            return EXIT_INTERRUPTED
        except InputError as exc:  # the driver's answer is malformed (checked_answer): one line, no traceback,
            print(f"error: {exc}", file=sys.stderr)  # the in-process runner's (it names the model)
            return EXIT_BAD_INPUT
        except PluginFault as exc:  # the driver raised: one line, a controller fault, the in-process runner's;
            print(f"error: {exc}", file=sys.stderr)  # the launcher tells the simulation, which aborts at once
            return EXIT_FAULT


def run_controller(name: str, command_spec: T.TopicSpec | Callable, build: Callable, args: list[str] | None) -> int:
    """``main`` of a controller node: one-line errors for bad parameters (exit 2)."""
    return run_node(lambda: ControllerNode(name, command_spec, build), args)
