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
* a node that dies is reported with its exit status; the run's status is non-zero if any
  node failed (the simulation node's status first: 3 = a controller fault, 130 = interrupted).

Environment of the nodes: ``ROS_DOMAIN_ID`` (random in 1..100 unless given), the Fast DDS
middleware with synchronous publication (``RMW_FASTRTPS_PUBLICATION_MODE``), and
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless a wider discovery range is asked for
(``SUBNET``, for ROS 2 users on other machines).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from evoscen_sim.config import ScenarioConfig
from evoscen_sim.node_params import scenario_parameters

NODES = (
    ("evoscen_eval", "evoscen_eval.eval_node"),
    ("evoscen_bv", "evoscen_bv.bv_node"),
    ("evoscen_sut", "evoscen_sut.sut_node"),
    ("evoscen_sim", "evoscen_sim.sim_node"),
)
DISCOVERY_RANGES = ("LOCALHOST", "SUBNET", "SYSTEM_DEFAULT")


@dataclass
class GraphOptions:
    """Settings of a graph run (defaults are the nodes' defaults)."""

    domain_id: int | None = None
    """ROS_DOMAIN_ID; None = random in 1..100 (drawn from the OS, not the scenario seed)."""
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
    """Users' node names the simulation waits for before step 0 (so they see every step)."""
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


def write_parameter_files(cfg: ScenarioConfig, out_dir: Path, bag_dir: Path, opts: GraphOptions) -> dict[str, Path]:
    """One ROS 2 parameter file per node in ``out_dir/params/``; returns their paths by node."""
    params_dir = out_dir / "params"
    params_dir.mkdir(parents=True, exist_ok=True)
    scenario = scenario_parameters(cfg)
    controllers = (["evoscen_bv"] if cfg.bvs.count > 0 else []) + ["evoscen_sut"]
    own = {
        "evoscen_sim": {"deadline_s": opts.deadline_s, "max_misses": opts.max_misses,
                        "startup_timeout_s": opts.startup_timeout_s, "controllers": controllers, "recorder": True,
                        "external_sut": opts.external_sut,
                        # a parameter file cannot type an empty list: only when there are nodes to wait for
                        **({"wait_for_nodes": list(opts.wait_for)} if opts.wait_for else {})},
        # no use_sim_time: the nodes take simulation time from the stamps of the messages they
        # answer or record; rclpy's time source would add a /clock reader per node that nothing
        # reads (no executor spins), and every step's /clock would be delivered to it
        "evoscen_bv": {"startup_timeout_s": opts.startup_timeout_s},
        "evoscen_sut": {"startup_timeout_s": opts.startup_timeout_s},
        "evoscen_eval": {"bag_dir": str(bag_dir), "external_sut": opts.external_sut,
                         **({"report_dir": str(opts.report_dir), "report_plots": opts.report_plots}
                            if opts.report_dir is not None else {})},
    }
    if opts.wait_for:  # the controllers wait for users' nodes too (a parameter file cannot type [])
        for name in ("evoscen_bv", "evoscen_sut"):
            own[name]["wait_for_nodes"] = list(opts.wait_for)
    paths = {}
    for name, _ in NODES:
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
    return env


def run_graph(cfg: ScenarioConfig, out_dir: Path, bag_dir: Path, opts: GraphOptions | None = None) -> GraphResult:
    """Run the scenario as a node graph (see the module docstring)."""
    opts = opts or GraphOptions()
    domain_id = opts.domain_id if opts.domain_id is not None else random.SystemRandom().randint(1, 100)
    params = write_parameter_files(cfg, out_dir, bag_dir, opts)
    env = node_environment(domain_id, opts.discovery_range)
    wanted = [(name, module) for name, module in NODES
              if (name != "evoscen_bv" or cfg.bvs.count > 0) and (name != "evoscen_sut" or not opts.external_sut)]
    procs: dict[str, subprocess.Popen] = {}
    t0 = time.monotonic()
    interrupted = False

    def forward(signum, frame):  # noqa: ANN001, ANN202
        nonlocal interrupted
        interrupted = True
        sim = procs.get("evoscen_sim")
        if sim is not None and sim.poll() is None:
            sim.send_signal(signal.SIGINT)

    old = {sig: signal.signal(sig, forward) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        for name, module in wanted:
            procs[name] = subprocess.Popen(
                [sys.executable, "-m", module, "--ros-args", "--params-file", str(params[name])],
                env=env, start_new_session=True,  # Ctrl-C reaches the launcher only; it decides
            )
        sim = procs["evoscen_sim"]
        while sim.poll() is None:
            early = [n for n, p in procs.items() if n != "evoscen_sim" and p.poll() not in (None, 0)]
            if "evoscen_eval" in early:  # no recorder: stop the run now, nothing would be recorded
                sim.send_signal(signal.SIGINT)
            time.sleep(0.05)
        for name in ("evoscen_eval", *[n for n in procs if n not in ("evoscen_eval", "evoscen_sim")]):
            _stop(procs[name], opts.shutdown_grace_s)
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
        for sig, handler in old.items():
            signal.signal(sig, handler)
    node_status = {name: p.returncode for name, p in procs.items()}
    sim_status = node_status["evoscen_sim"]
    others = [s for n, s in node_status.items() if n != "evoscen_sim" and s not in (0, None)]
    status = sim_status if sim_status != 0 else (others[0] if others else 0)
    if interrupted and status == 0:
        status = 130
    return GraphResult(status=status, node_status=node_status, domain_id=domain_id,
                       wall_time_s=time.monotonic() - t0)


def _stop(proc: subprocess.Popen, grace_s: float) -> None:
    """Let ``proc`` end by itself for ``grace_s``, then SIGINT, then SIGKILL."""
    for sig, wait_s in ((None, grace_s), (signal.SIGINT, 10.0), (signal.SIGKILL, 10.0)):
        if sig is not None and proc.poll() is None:
            proc.send_signal(sig)
        try:
            proc.wait(timeout=wait_s)
            return
        except subprocess.TimeoutExpired:
            continue
