"""The one step loop both runners drive (no ROS here).

Step ``k`` (time ``t_k``), in this order:

1. :meth:`Port.begin_step` (the simulation node: Ctrl-C check, flow control);
2. the state at ``t_k`` goes out: :meth:`Port.send_world` (``/evoscen/world``, and before the
   first step the roster and the map markers) — what the controllers wait for — then the
   events of the step that led to ``t_k`` (:meth:`Port.send_events`, stamped ``t_k``; every
   step, ``[]`` when nothing happened; worked out only now, off the controllers' critical
   path), then the rest of the state (:meth:`Port.send_state`: ``/clock``, odometry, markers);
3. :meth:`Port.commands` answers with the throttle and lane-change commands for every
   vehicle (and, from the simulation node, the ``fault`` events of the collection, each list
   one ``/evoscen/events`` message, sent in order, stamped ``t_k``; or an abort);
4. the world integrates to ``t_{k+1}`` (:meth:`Port.stepped` sees the result).

The events of a step are, in this order: the initial state's exposure events (with the first
step's only), :func:`~evoscen_sim.danger.events.step_events`, then the exposure events of the new
state (:class:`~evoscen_sim.danger.events.ExposureMonitor`, which observes every state, the initial
one included).

The run ends completed after the last step, aborted when :meth:`Port.start` or
:meth:`Port.commands` says so (:class:`RunAborted`), interrupted on Ctrl-C
(``KeyboardInterrupt``). Every ending sends the final state (unless it went out already: an
abort or Ctrl-C after a state was sent), with the events of the last step, then one
``run_end`` event. A run of N steps thus sends N+1 states.

What differs between the runners lives in their ports:

* the in-process runner (:mod:`evoscen_bringup.inprocess`) calls the scenario's drivers for
  the commands and records every message to the bag (and the evaluator's accumulator);
  ``finish_on_error``: any other exception ends the run ``interrupted`` too, so the bag is
  finished, and is raised again;
* the simulation node (:mod:`evoscen_sim.nodes.sim_node`) waits for the graph at start-up, keeps
  flow control towards the recorder, publishes on the contract's topics and collects the
  controllers' commands with deadlines: a missed deadline or a malformed answer holds the
  controller's last throttle, wire and deadline ``fault`` events come back with the
  commands, ``max_misses`` misses abort the run. These events exist only in the node graph
  (in-process drivers cannot miss a deadline); they go into the same stream, after the
  step's events, in the order the node found the faults. Any other exception in the node
  propagates without a ``run_end`` (the launcher reports the node's death).
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Generator
from dataclasses import dataclass, field

import numpy as np

from evoscen_contract.contract import KIND_ABORTED, KIND_COMPLETED, KIND_INTERRUPTED
from evoscen_sim.danger.events import ExposureMonitor, challenge_end_event, run_end_event, step_events


class RunAborted(RuntimeError):
    """The run cannot go on (a controller fault or a start-up timeout); the message says why."""


@dataclass
class Commands:
    """A port's answer for one step: a command for every vehicle (world order)."""

    throttle: np.ndarray
    lane_change: np.ndarray
    events: list[list[dict]] = field(default_factory=list)
    """Events found while collecting the commands (the node's faults): each list is one
    ``/evoscen/events`` message, sent in order before the step, stamped ``t_k``."""
    abort: str | None = None
    """Set when the run cannot go on: the events are sent, then the run ends ``aborted`` with
    this text (the world is not stepped)."""


@dataclass
class Outcome:
    """How a run ended."""

    kind: str
    """``run_end`` kind: completed, aborted or interrupted."""
    text: str
    """``run_end`` message."""
    steps: int
    """Steps done."""
    wall_s: float | None
    """Wall time of the steps (after :meth:`Port.start`); None when start-up did not finish."""


class Port(ABC):
    """What a runner plugs into :class:`StepLoop`: where the messages go, where commands come from."""

    def start(self) -> None:  # noqa: B027 - a hook: most ports have no start-up
        """Before step 0 (the node: wait until the graph is matched). May raise :class:`RunAborted`."""

    def begin_step(self, step: int) -> None:  # noqa: B027 - a hook
        """Before the state of ``step`` goes out (the node: Ctrl-C check, flow control)."""

    @abstractmethod
    def send_world(self, world, *, roster: bool) -> None:  # a World
        """The world at ``t_k`` (and, with ``roster``, the roster and the map markers)."""

    @abstractmethod
    def send_events(self, events: list[dict], t_ns: int) -> None:
        """One ``/evoscen/events`` message stamped ``t_ns``."""

    @abstractmethod
    def send_state(self, world) -> None:  # a World
        """The rest of the state at ``t_k``: ``/clock``, odometry, markers when due."""

    @abstractmethod
    def commands(self, step: int) -> Commands:
        """The commands for ``step`` (answering the world at ``t_k``)."""

    def stepped(self, step: int, result) -> None:  # noqa: B027 - a hook; a StepResult
        """After the world integrated ``step`` (``result``: :meth:`evoscen_sim.physics.world.World.step`'s)."""


class StepLoop:
    """Runs a world through a :class:`Port` (see the module docstring).

    ``interrupted_text`` is the ``run_end`` message of a Ctrl-C ending; with
    ``finish_on_error`` any other exception also ends the run (``interrupted``) before it is
    raised again.
    """

    def __init__(self, world, evaluation, port: Port, *, interrupted_text: str = "run interrupted",
                 finish_on_error: bool = False) -> None:
        self.world = world
        self.port = port
        self.exposures = ExposureMonitor(evaluation, world.role)
        self.interrupted_text = interrupted_text
        self.finish_on_error = finish_on_error
        self._state_ns: int | None = None  # the time of the last state sent
        self._stepped = None  # the result of the last step, until its events go out with the next state
        self._initial: list[dict] = []

    def run(self, steps: int) -> Outcome:
        """Start, run ``steps`` steps, end; Ctrl-C and :class:`RunAborted` end the run early."""
        stepping = self.stepping(steps)
        interrupt: KeyboardInterrupt | None = None
        while True:
            try:
                if interrupt is None:
                    next(stepping)
                else:  # a Ctrl-C that came between two steps ends the run as one within a step
                    interrupt, pending = None, interrupt
                    stepping.throw(pending)
            except StopIteration as done:
                return done.value
            except KeyboardInterrupt as exc:
                if stepping.gi_frame is None:  # raised by the run's own ending: not ours to handle
                    raise
                interrupt = exc

    def stepping(self, steps: int) -> Generator[int, None, Outcome]:
        """:meth:`run` one step at a time: yields ``k`` after step ``k``, returns the :class:`Outcome` (as
        :meth:`run` does) when the run has ended. Many runs advanced in turn step in lockstep
        (:func:`evoscen_bringup.inprocess.run_plans`); a run ends the same way whether advanced so or by
        :meth:`run`."""
        w, port = self.world, self.port
        # an exposure in the initial state goes out with the first events
        self._initial = self.exposures.observe(w)
        t0 = None
        try:
            port.start()
            t0 = time.perf_counter()
            for k in range(steps):
                port.begin_step(k)
                self._send_state(roster=(k == 0))
                cmds = port.commands(k)
                for events in cmds.events:
                    port.send_events(events, w.time_ns)
                if cmds.abort is not None:
                    raise RunAborted(cmds.abort)
                # its events go out with the next state
                self._stepped = w.step(cmds.throttle, cmds.lane_change)
                port.stepped(k, self._stepped)
                yield k
            kind, text = KIND_COMPLETED, f"run completed: {w.step_index} steps"
        except RunAborted as exc:
            kind, text = KIND_ABORTED, str(exc)
        except KeyboardInterrupt:
            kind, text = KIND_INTERRUPTED, self.interrupted_text
        except BaseException:
            if self.finish_on_error:
                self._end(KIND_INTERRUPTED, self.interrupted_text)
            raise
        wall_s = time.perf_counter() - t0 if t0 is not None else None
        self._end(kind, text)
        return Outcome(kind=kind, text=text, steps=w.step_index, wall_s=wall_s)

    def _send_state(self, *, roster: bool) -> None:
        w, port = self.world, self.port
        self._state_ns = w.time_ns
        port.send_world(w, roster=roster)
        if self._stepped is not None:  # what happened in the step that led to t_k
            events = self._initial + step_events(w, self._stepped) + self.exposures.observe(w)
            self._stepped, self._initial = None, []
            port.send_events(events, w.time_ns)
        port.send_state(w)

    def _end(self, kind: str, text: str) -> None:
        """The final state (unless it went out already: abort, Ctrl-C), then ``run_end``."""
        w = self.world
        if w.time_ns != self._state_ns:
            self._send_state(roster=(w.step_index == 0))
        challenge = challenge_end_event(w)
        self.port.send_events(([challenge] if challenge is not None else []) + [run_end_event(w, kind, text)],
                              w.time_ns)
