"""The node-graph runner: one process per node, supervised, on a fresh ROS 2 domain.

:func:`run_graph` writes one ROS 2 parameter file per node (``node: ros__parameters:`` with
the node's settings and the scenario configuration under ``scenario``), starts the
evaluator (recorder), the BV node, the SUT node and the simulation node as separate
processes (``python -m <pkg>.<node> --ros-args --params-file ...``), and supervises them:

* the simulation node's exit ends the run; the evaluator then finishes the bag on the
  ``run_end`` event (or on SIGINT if it does not, then SIGKILL as a last resort), and the
  controllers exit on ``run_end`` too (or are stopped the same way);
* Ctrl-C (SIGINT/SIGTERM to the launcher) is forwarded to the simulation node only, which
  ends the run after the current step, so the bag is finished in every case;
* a node that dies is named in the launcher's log with how it ended (``evoscen_eval ended early
  (killed by SIGKILL (signal 9))``), and the graph ends within seconds: the evaluator's death or
  any death during start-up (before the simulation node's ``ready_file`` exists) stops the
  simulation node at once (SIGINT); a controller whose process ended in the lockstep (killed, or
  ended with its own fault line: its driver raised, status 3) is named in the simulation's
  ``deaths_file`` at once, and the simulation aborts the run at the step it waits for (a ``fault``
  event of kind ``abort`` in the bag; no deadline waits), its abort line saying that it is a
  consequence (no second ``error:`` line), with a SIGINT after ``deadline_s`` · ``max_misses`` + 5 s
  as a backstop; the simulation node's death sends SIGTERM to the evaluator (which
  finishes the bag) and SIGINT to the controllers, SIGKILL after 5 s;
* each node's output (its lines, rclpy's log lines, a traceback) goes to ``OUT/logs/<node>.log``
  (:mod:`evoscen_bringup.node_logs`), the launcher's own events to ``OUT/logs/launcher.log``; the
  terminal gets one ``error:`` line for a run that failed: the launcher's for a death (4), else the line
  of the node whose status decided (the in-process runner's words), ending ``(node logs: OUT/logs/)``;
* the exit status is one of :data:`EXIT_OK` 0, :data:`EXIT_BAD_INPUT` 2, :data:`EXIT_FAULT` 3,
  :data:`EXIT_NODE_DIED` 4, :data:`EXIT_HOST_FAULT` 5, :data:`EXIT_INTERRUPTED` 130 (:func:`graph_status`), never a raw
  signal number.

Environment of the nodes: ``ROS_DOMAIN_ID`` (a free one of 1..100 unless given: reserved on this
host for the run, :mod:`evoscen_bringup.domains`), the Fast DDS
middleware with synchronous publication (``RMW_FASTRTPS_PUBLICATION_MODE``), and
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless a wider discovery range is asked for
(``SUBNET``, for ROS 2 users on other machines).
"""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from evoscen_contract.contract import (EXIT_BAD_INPUT, EXIT_FAULT, EXIT_HOST_FAULT, EXIT_INTERRUPTED, EXIT_NODE_DIED,
                                       EXIT_OK, NODE_BV, NODE_EVAL, NODE_EXIT_STATUSES, NODE_SIM, NODE_SUT)
from evoscen_sim.config.scenario_config import ScenarioConfig
from evoscen_sim.model_registry import QUIET_ENV as PLUGIN_WARNINGS_SHOWN
from evoscen_sim.nodes.bv_nodes import bv_node_names
from evoscen_sim.nodes.node_params import scenario_parameters

from evoscen_bringup.domains import reserve_domain
from evoscen_bringup.node_logs import LAUNCHER_LOG, LOG_DIR, Errors, LauncherLog, NodeLog, the_error_line

NODES = (
    (NODE_EVAL, "evoscen_eval.eval_node"),
    (NODE_BV, "evoscen_bv.bv_node"),  # one process per BV node of bvs.nodes (bv_node_names)
    (NODE_SUT, "evoscen_sut.sut_node"),
    (NODE_SIM, "evoscen_sim.nodes.sim_node"),
)
BV_MODULE = "evoscen_bv.bv_node"
"""The program of every BV node; the launcher names each one (``-r __node:=evoscen_bv_<part>``)."""
STOP_GRACE_S = 5.0
"""How long nodes get to end by themselves when the run ended before step 0 or the simulation died."""
SIM_STOP_ESCALATE_S = 3.0
"""When the launcher stops the simulation (a node died), SIGTERM follows the first signal after
this long and SIGKILL after twice this long, so the graph ends within seconds in every case."""


@dataclass
class GraphOptions:
    """Settings of a graph run (defaults are the nodes' defaults)."""

    domain_id: int | None = None
    """ROS_DOMAIN_ID; None = a free one of 1..100 reserved for the run (:mod:`evoscen_bringup.domains`);
    an explicit one is used as given (``run_scenario.py`` reserves it first)."""
    discovery_range: str = "LOCALHOST"
    """ROS_AUTOMATIC_DISCOVERY_RANGE of the nodes."""
    deadline_s: float = 2.0
    """Per-step deadline of each controller (wall clock)."""
    max_misses: int = 5
    """Consecutive missed deadlines that abort the run."""
    startup_timeout_s: float = 60.0
    """How long the nodes wait for each other at start-up."""
    shutdown_grace_s: float = 30.0
    """How long the launcher waits for a node to end by itself before signalling it."""
    node_args: dict[str, dict] = field(default_factory=dict)
    """Extra parameters per node name (tests)."""
    wait_for: tuple[str, ...] = ()
    """Users' node names the simulation waits for before step 0 (so they see every step). A BV node
    of the scenario named here is not started by the launcher: it is started by hand (another
    terminal or machine, same domain) with its parameter file ``OUT/params/<name>.yaml``, and the
    simulation waits for it like for every controller."""
    report_dir: Path | None = None
    """Where the evaluator writes the report (report.json, report.md, plots); None = no report."""
    report_plots: bool = True
    """Draw the report's PNG plots."""
    external_sut: bool = False
    """Do not start evoscen's SUT node: a user's own node answers on ``/evoscen/commands/sut``
    (the simulation node waits for it at start-up like for any controller)."""


@dataclass
class GraphResult:
    """Exit statuses of the run and of each node."""

    status: int
    node_status: dict[str, int | None]
    domain_id: int
    wall_time_s: float
    died: dict[str, str] = field(default_factory=dict)
    """Nodes that died or ended before the run did, with how (``killed by SIGKILL (signal 9)``)."""
    deaths: list[str] = field(default_factory=list)
    """The nodes of ``died`` that died (killed by a signal, or ended non-zero on their own), in order."""
    error: str | None = None
    """The run's one ``error:`` line as printed (None: none), naming the node logs where they are whole."""
    log_dir: Path | None = None
    """The nodes' log files (``<node>.log``) and the launcher's ``launcher.log``."""


def write_parameter_files(cfg: ScenarioConfig, out_dir: Path, bag_dir: Path, opts: GraphOptions) -> dict[str, Path]:
    """One ROS 2 parameter file per node in ``out_dir/params/``; returns their paths by node."""
    params_dir = out_dir / "params"
    params_dir.mkdir(parents=True, exist_ok=True)
    scenario = scenario_parameters(cfg)
    bv_names = bv_node_names(cfg)
    controllers = bv_names + [NODE_SUT]
    own = {
        NODE_SIM: {"deadline_s": opts.deadline_s, "max_misses": opts.max_misses,
                        "startup_timeout_s": opts.startup_timeout_s, "controllers": controllers, "recorder": True,
                        "external_sut": opts.external_sut,
                        # a parameter file cannot type an empty list: only when there are nodes to wait for
                        **({"wait_for_nodes": list(opts.wait_for)} if opts.wait_for else {})},
        # no use_sim_time: the nodes take simulation time from the stamps of the messages they
        # answer or record; rclpy's time source would add a /clock reader per node that nothing
        # reads (no executor spins), and every step's /clock would be delivered to it
        NODE_BV: {"startup_timeout_s": opts.startup_timeout_s},
        NODE_SUT: {"startup_timeout_s": opts.startup_timeout_s},
        NODE_EVAL: {"bag_dir": str(bag_dir), "external_sut": opts.external_sut,
                         **({"report_dir": str(opts.report_dir), "report_plots": opts.report_plots}
                            if opts.report_dir is not None else {})},
    }
    bv_own = {**own.pop(NODE_BV), **opts.node_args.get(NODE_BV, {})}
    for name in bv_names:  # every BV node of bvs.nodes: the BV node's settings (node_args under evoscen_bv too)
        own[name] = dict(bv_own)
    if opts.wait_for:  # the controllers wait for users' nodes too (a parameter file cannot type [])
        for name in (*bv_names, NODE_SUT):
            others = [n for n in opts.wait_for if n != name]  # a BV node started by hand: not for itself
            if others:
                own[name]["wait_for_nodes"] = others
    paths = {}
    for name in own:
        params = {**own[name], **opts.node_args.get(name, {}), "scenario": scenario}
        path = params_dir / f"{name}.yaml"
        path.write_text(yaml.safe_dump({name: {"ros__parameters": params}}, sort_keys=False), encoding="utf-8")
        paths[name] = path
    return paths


def node_environment(domain_id: int, discovery_range: str) -> dict[str, str]:
    """The environment of the node processes."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    # synchronous publication: the message goes out in publish() itself. The rmw's default
    # (asynchronous) hands every message to a writer thread: in a lockstep loop that only adds
    # latency (measured here: 391 vs 866 steps/s). A value set by the user is kept.
    env.setdefault("RMW_FASTRTPS_PUBLICATION_MODE", "SYNCHRONOUS")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; the discovery range decides
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
    env["PYTHONUNBUFFERED"] = "1"
    env[PLUGIN_WARNINGS_SHOWN] = "1"  # the launcher warned of broken plug-ins; its nodes keep quiet about them
    return env


def describe_status(returncode: int | None) -> str:
    """A process's end in words: ``exit status 1``, ``killed by SIGKILL (signal 9)``."""
    if returncode is None:
        return "still running"
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"killed by {name} (signal {-returncode})"
    return f"exit status {returncode}"


def _wanted_nodes(cfg: ScenarioConfig, opts: GraphOptions) -> list[tuple[str, str]]:
    """The nodes the launcher starts, as (node name, module): one BV node per share of ``bvs.nodes``,
    each under its own name, but for one named in ``wait_for`` (started by hand, docs/architecture.md
    §5); no SUT node for an external SUT."""
    wanted = []
    for name, module in NODES:
        if name == NODE_BV:
            wanted += [(bv, module) for bv in bv_node_names(cfg) if bv not in opts.wait_for]
        elif name != NODE_SUT or not opts.external_sut:
            wanted.append((name, module))
    return wanted


def _node_ended(name: str, returncode: int, ready_file: Path, died: dict[str, str], note, tell_simulation,
                stop_sim_at: float | None, fault_wait_s: float, log: LauncherLog) -> float | None:
    """Node ``name`` (not the simulation) ended before the run with ``returncode`` (not 0): how is noted
    in ``died`` (``note``: a death; ``tell_simulation``: the simulation is told in the lockstep), and
    the answer is when to stop the simulation (``stop_sim_at``, updated)."""
    started = ready_file.exists()
    if name == NODE_EVAL and returncode == EXIT_HOST_FAULT:
        # the recorder could not write (a full disk): it said so in one line and
        # finished what it could of the bag; not a death: stop the run now
        died[name] = "could not write its output"
        return time.monotonic()
    if name in (NODE_SUT, NODE_BV) and returncode == EXIT_BAD_INPUT and ready_file.exists():
        # a controller refused its driver's answer (NaN, a wrong shape: models.checked_answer)
        # and said so in one line: bad input, not a death; stop the run now rather than
        # let the simulation wait out its deadlines
        died[name] = "refused its driver's answer"
        return time.monotonic()
    if name != NODE_EVAL and returncode == EXIT_FAULT:
        # a controller fault the controller said in its one line (its driver raised, its
        # start-up timed out): not a death. In the lockstep the simulation, told at once,
        # aborts the run at the step it waits for (no deadline waits); in start-up: stop it
        died[name] = "ended with a controller fault (exit status 3)"
        log(f"{name} {died[name]}")
        if started:
            tell_simulation(name)
            return time.monotonic() + fault_wait_s if stop_sim_at is None else stop_sim_at
        return time.monotonic()
    note(name, f"ended early ({describe_status(returncode)})" + ("" if started else " during start-up"))
    if name == NODE_EVAL or not started:
        # no recorder: nothing would be recorded; during start-up: the simulation would
        # wait out its start-up timeout for the dead node. Stop the run now.
        return time.monotonic()
    # a controller in the lockstep: the simulation's deadline misses abort the run
    # (fault events in the bag; exit status 4, the abort is its consequence); stop
    # it if that does not happen in time
    tell_simulation(name)
    return time.monotonic() + fault_wait_s if stop_sim_at is None else stop_sim_at


def _stop_the_others(sim: subprocess.Popen, procs: dict[str, subprocess.Popen], ready_file: Path,
                     signalled: set[str], note, opts: GraphOptions) -> None:
    """The simulation has ended: note its death if it died, and stop the other nodes (at once, together,
    when it died or the run never reached step 0; else each within ``opts.shutdown_grace_s``)."""
    started = ready_file.exists()
    sim_died = sim.returncode not in NODE_EXIT_STATUSES and not (
        NODE_SIM in signalled and sim.returncode == -signal.SIGTERM)
    if sim_died and NODE_SIM in signalled and sim.returncode == -signal.SIGKILL:
        note(NODE_SIM, "did not end on SIGINT/SIGTERM and was stopped with SIGKILL")
    elif sim_died:
        note(NODE_SIM, f"died ({describe_status(sim.returncode)})")
    if sim_died or not started:
        # nobody will end the run for the others (the simulation died), or they never saw
        # step 0 and would wait out their start-up timeouts: stop them all now, together.
        # The evaluator finishes the bag on SIGTERM; SIGTERM before step 0 (a node still
        # importing would print a KeyboardInterrupt traceback on SIGINT); SIGKILL after 5 s.
        alive = [n for n in procs if n != NODE_SIM and procs[n].poll() is None]
        for name in alive:
            use_int = started and name != NODE_EVAL
            procs[name].send_signal(signal.SIGINT if use_int else signal.SIGTERM)
            signalled.add(name)
        end = time.monotonic() + STOP_GRACE_S
        for name in alive:
            _stop(procs[name], max(end - time.monotonic(), 0.0), signals=(signal.SIGKILL,))
    else:
        for name in (NODE_EVAL, *[n for n in procs if n not in (NODE_EVAL, NODE_SIM)]):
            _stop(procs[name], opts.shutdown_grace_s)


def _death_line(node_status: dict[str, int | None], died: dict[str, str], deaths: list[str]) -> str:
    """What the error line of a run with a dead node says: the first node that died and how, or else
    every node that ended badly."""
    if deaths or died:
        first = deaths[0] if deaths else next(iter(died))
        return f"node {first} {died[first]}; the run ended early"
    # every node outlived the run, but one ended badly (e.g. stopped by the launcher)
    return "; ".join(f"node {n} ended with {describe_status(s)}" for n, s in node_status.items()
                     if s not in (0, None))


def _error_line(status: int, node_status: dict[str, int | None], died: dict[str, str], deaths: list[str],
                errors: Errors, logs: list[NodeLog], log: LauncherLog) -> str | None:
    """The run's one ``error:`` line, printed on stderr (None: the run has none): the launcher's for a death,
    else the deciding node's (:func:`~evoscen_bringup.node_logs.the_error_line`), naming the log folder
    where every log is whole."""
    end = time.monotonic() + 2.0  # the output of a node's own child processes, if any outlived it: 2 s in all
    for node_log in logs:
        node_log.join(max(end - time.monotonic(), 0.0))
    log(f"ended: exit status {status}; " + ", ".join(f"{n} {describe_status(s)}" for n, s in node_status.items()))
    if status == EXIT_NODE_DIED:
        line = f"graph: {_death_line(node_status, died, deaths)} (exit status {EXIT_NODE_DIED})"
    else:
        line = the_error_line(status, node_status, errors.lines())
    if line is None:
        return None
    whole = log.complete and all(node_log.complete for node_log in logs)
    line = f"error: {line}" + (f" (node logs: {log.path.parent}/)" if whole else "")
    print(line, file=sys.stderr)
    return line


def run_graph(cfg: ScenarioConfig, out_dir: Path, bag_dir: Path, opts: GraphOptions | None = None) -> GraphResult:
    """Run the scenario as a node graph (see the module docstring)."""
    opts = opts or GraphOptions()
    if opts.domain_id is None:  # reserve a free domain for the run (evoscen_bringup.domains)
        with reserve_domain(None) as domain:
            return run_graph(cfg, out_dir, bag_dir, dataclasses.replace(opts, domain_id=domain))
    domain_id = opts.domain_id
    ready_file = out_dir / "params" / ".evoscen_sim.ready"
    deaths_file = out_dir / "params" / ".evoscen_sim.deaths"
    opts = dataclasses.replace(opts, node_args={
        **opts.node_args, NODE_SIM: {"ready_file": str(ready_file), "deaths_file": str(deaths_file),
                                     **opts.node_args.get(NODE_SIM, {})}})
    params = write_parameter_files(cfg, out_dir, bag_dir, opts)
    ready_file.unlink(missing_ok=True)
    deaths_file.unlink(missing_ok=True)
    log_dir = out_dir / LOG_DIR
    log_dir.mkdir(exist_ok=True)
    for old_log in log_dir.glob("*.log"):  # a previous run's, in this output directory
        old_log.unlink()
    env = node_environment(domain_id, opts.discovery_range)
    wanted = _wanted_nodes(cfg, opts)
    procs: dict[str, subprocess.Popen] = {}
    logs: list[NodeLog] = []
    errors = Errors()
    t0 = time.monotonic()
    log = LauncherLog(log_dir / LAUNCHER_LOG, t0)
    interrupted = False
    died: dict[str, str] = {}  # node -> how it ended, for nodes that ended before the run did
    deaths: list[str] = []  # the nodes of died that died (killed, or non-zero on their own): exit status 4
    signalled: set[str] = set()  # nodes the launcher stopped itself

    def forward(signum, frame):
        nonlocal interrupted
        interrupted = True
        sim = procs.get(NODE_SIM)
        if sim is not None and sim.poll() is None:
            sim.send_signal(signal.SIGINT)

    def note(name: str, why: str) -> None:
        died[name] = why
        deaths.append(name)
        log(f"{name} {why}")

    ended: list[str] = []  # controllers whose process ended in the lockstep, named in deaths_file

    def tell_simulation(name: str) -> None:
        """A controller's process ended in the lockstep: name it in the simulation's ``deaths_file``
        (written whole, then renamed); the simulation aborts the run at the step it waits for, its
        abort line saying that it is a consequence."""
        ended.append(name)
        part = deaths_file.with_name(deaths_file.name + ".part")
        try:
            part.write_text("".join(f"{n}\n" for n in ended), encoding="utf-8")
            os.replace(part, deaths_file)
        except OSError:  # the output directory is gone or full: the abort line keeps its 'error:'
            pass

    old = {sig: signal.signal(sig, forward) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for name, module in wanted:
            rename = ["-r", f"__node:={name}"] if module == BV_MODULE else []
            procs[name] = subprocess.Popen(
                [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[name]), *rename],
                env=env, start_new_session=True,  # Ctrl-C reaches the launcher only; it decides
                stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,  # to its log file
            )
            logs.append(NodeLog(name, procs[name].stdout, log_dir / f"{name}.log", errors))
            log(f"{name} started (pid {procs[name].pid})")
        sim = procs[NODE_SIM]
        fault_wait_s = opts.deadline_s * opts.max_misses + 5.0
        stop_sim_at: float | None = None
        escalate: list[tuple[float, int]] = []  # (when, signal): if the simulation outlives its stop signal
        while sim.poll() is None:
            for name, p in procs.items():
                if name == NODE_SIM or name in died or p.poll() in (None, 0):
                    continue  # 0: a controller answered the final state, the recorder got run_end
                stop_sim_at = _node_ended(name, p.returncode, ready_file, died, note, tell_simulation, stop_sim_at,
                                          fault_wait_s, log)
            if stop_sim_at is not None and time.monotonic() >= stop_sim_at:
                # SIGTERM before step 0: a node still importing its modules would print a
                # KeyboardInterrupt traceback on SIGINT (the simulation handles both alike)
                sim.send_signal(signal.SIGINT if ready_file.exists() else signal.SIGTERM)
                signalled.add(NODE_SIM)
                stop_sim_at = float("inf")  # once
                escalate = [(time.monotonic() + SIM_STOP_ESCALATE_S, signal.SIGTERM),
                            (time.monotonic() + 2 * SIM_STOP_ESCALATE_S, signal.SIGKILL)]
            while escalate and time.monotonic() >= escalate[0][0]:
                # the simulation did not end on the first signal: measured, a SIGINT that reached it
                # while it waited for a killed recorder's acknowledgements was sometimes not acted
                # on, and the wait lasted until the recorder's participant lease ran out (60 s)
                sim.send_signal(escalate.pop(0)[1])
            time.sleep(0.05)
        _stop_the_others(sim, procs, ready_file, signalled, note, opts)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
        for sig, handler in old.items():
            signal.signal(sig, handler)
        for marker in (ready_file, deaths_file):
            try:
                marker.unlink(missing_ok=True)
            except OSError:  # the output became read-only or was removed: the recorder's line says so
                pass
    node_status = {name: p.returncode for name, p in procs.items()}
    status = graph_status(node_status, died, interrupted, deaths)
    line = _error_line(status, node_status, died, deaths, errors, logs, log)
    return GraphResult(status=status, node_status=node_status, domain_id=domain_id,
                       wall_time_s=time.monotonic() - t0, died=died, deaths=deaths, error=line, log_dir=log_dir)


def graph_status(node_status: dict[str, int | None], died: dict[str, str], interrupted: bool,
                 deaths: Collection[str] = ()) -> int:
    """The launcher's exit status (table in docs/recording.md).

    The simulation node's bad input (2) first, then 2 from any node (a bad parameter, or a controller
    that refused its driver's answer: a controller fault that follows is its consequence), then 5
    from the recorder (a fault of the host: it could not write the bag and stopped the run), then 3
    from a controller of ``died`` that is not in ``deaths`` (it said its fault in one line: its driver
    raised, docs/plugins.md §3; the abort that follows is its consequence), then a
    node that died (4: ``deaths``, killed by a signal or ended non-zero on its own before the run
    did; the simulation's deadline abort that follows a controller's death is its consequence), then
    the simulation node's 3 (a controller fault: a live controller missed its deadlines, or start-up
    timed out), then any other node of ``died`` (4), then an interruption (130), then any other
    node's failure (3 if all are 3, else 4); 0 only if every node ended with 0.
    """
    sim = node_status.get(NODE_SIM)
    if sim == EXIT_BAD_INPUT:
        return sim
    others = [s for n, s in node_status.items() if n != NODE_SIM and s not in (0, None)]
    if EXIT_BAD_INPUT in others:  # before the simulation's fault: a controller that refused its driver's
        return EXIT_BAD_INPUT     # answer left the lockstep, and any fault that followed is its consequence
    if EXIT_HOST_FAULT in others:  # the recorder could not write: it stopped the run (its one line)
        return EXIT_HOST_FAULT
    if any(node_status.get(n) == EXIT_FAULT for n in died if n not in deaths and n not in (NODE_SIM, NODE_EVAL)):
        return EXIT_FAULT  # a controller that ended with its own fault line (its driver raised): the abort follows
    if deaths:  # a death; an abort of the simulation that followed it is its consequence
        return EXIT_NODE_DIED
    if sim == EXIT_FAULT:
        return sim
    if died:
        return EXIT_NODE_DIED
    if interrupted or sim == EXIT_INTERRUPTED:
        return EXIT_INTERRUPTED
    if others:
        return EXIT_FAULT if all(s == EXIT_FAULT for s in others) else EXIT_NODE_DIED
    return EXIT_OK if sim == 0 else EXIT_NODE_DIED


def _stop(proc: subprocess.Popen, grace_s: float,
          signals: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGKILL)) -> None:
    """Let ``proc`` end by itself for ``grace_s``, then each of ``signals`` in turn (10 s each)."""
    for sig, wait_s in ((None, grace_s), *((s, 10.0) for s in signals)):
        if sig is not None and proc.poll() is None:
            proc.send_signal(sig)
        try:
            proc.wait(timeout=wait_s)
            return
        except subprocess.TimeoutExpired:
            continue
