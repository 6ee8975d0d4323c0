"""The fault-and-fuzz campaign: kills, stalls and hostile messages in node graphs, faults of the host,
fuzzed inputs — ``scripts/fault_campaign.py``'s work (docs/recording.md, "Fault campaign").

:func:`run_campaign` takes the fault classes in turn (:func:`fault_classes`), each run a graph run of
the checkout's ``scripts/run_scenario.py`` (:func:`graph_run`) or a fault of the host
(:mod:`evoscen_experiments.host_faults`), then the fuzzed inputs (:mod:`evoscen_experiments.input_fuzz`),
and prints one line per run and the summary table (:func:`summary_rows`); the results are
:class:`~evoscen_experiments.fault_runs.GraphResult`.

Graph runs (``run_scenario.py --mode graph``, deadline 0.5 s, 3 misses), one fault each, the
fault classes taken in turn and their timing drawn from a generator seeded by ``--seed``:

* SIGKILL or SIGTERM to each node (simulation, each of the three BV nodes of ``bvs.nodes:
  by_policy`` — competitive, mutual, cooperative —, SUT, evaluator), during start-up or during the
  lockstep (24 classes): a death, status 4 with the launcher's ``error: graph: node NAME ...`` line
  naming the node (a SIGTERMed simulation ends the run as interrupted instead: 130 in the lockstep,
  4 or 130 in start-up, as the signal comes before or after its handler is installed); a
  controller (BV or SUT node) killed in the lockstep must also leave the simulation's ``fault``
  event of kind ``abort`` naming it in the finished bag, and that ``error:`` line must be the only one;
* the evaluator stalled (SIGSTOP) for 2-30 s (``--max-stall``), then resumed;
* a hostile node on the run's domain (``tests/wire_intruder.py``: foreign and malformed
  commands, garbage world messages, forged events) — the world table must equal a clean
  in-process run of the same seed byte for byte. The run waits for it (``--wait-for intruder``:
  discovering an outside node can take seconds on a loaded machine) and it must have attacked at
  least half of the world messages.

Faults of the host (docs/recording.md, "Faults of the host"; ``sudo``/root for the tmpfs):

* ``enospc:inline``, ``enospc:process``, ``enospc:graph``: the run's output on a tmpfs of a size
  drawn from 150 to 1,500 KiB (the script mounts it and removes it), so the disk fills at a random
  step: status 5 with one ``error:`` line (0 if everything fit), and the bag (after ``reindex`` if
  the line asks for it) holds exactly the world states the line names, steps 0..N-1;
* ``vanish:process``: the output directory removed while the bag is written (at a size drawn
  from 20 to 400 kB): status 5, one line saying the bag is gone;
* ``driver-kill``: a campaign of 8 short runs whose driver alone is SIGKILLed after its first
  result, then the same command: status 0, every run exactly once, no process of the killed
  driver's Ray left running.

* ``readonly:inline``, ``readonly:process``, ``readonly:graph``: the run's output on a small
  ext4 file system (a 64 MiB image on a loop device, mounted ``errors=remount-ro``) that is made
  read-only while the bag is written (at a size drawn from 20 to 400 kB), as the kernel does on an
  I/O error: ext4's ``trigger_fs_error``. Writes to the files already open then fail with EROFS,
  for root too (``mount -o remount,ro`` refuses a file system with files open for writing: EBUSY).
  Status 5, one ``error:`` line naming the bag file and ``Read-only file system (EROFS)``, the run
  ended within 10 s of the fault, and the bag, read-only so not finished, holds after ``reindex``
  (of a copy) exactly the world states the line names, steps 0..N-1.

For each run: the exit status (documented: 0, 2, 3, 4, 5, 130), seconds from the fault to the end
of the graph (≤ 10 s), a hang (no end within 120 s), tracebacks, orphans (processes of the run
still running once the launcher ended: 0 allowed), whether the bag opens (after
``reindex`` if it has to), and steps lost (world states published by the simulation but missing
from the bag; ≤ 10 = 1 s allowed after a SIGKILLed evaluator, 0 otherwise). To count what the
evaluator had been sent, a SIGKILL to it during the lockstep freezes the simulation (SIGSTOP)
first and resumes it once the evaluator is gone; the one or two steps the simulation makes after
SIGCONT, before the launcher's stop takes effect, are allowed on top — up to the flow-control
window (50 steps), because that stop is sometimes acted on seconds late (docs/recording.md). A SIGTERMed evaluator
writes everything it received, so only gaps count there (not a frozen lockstep: an evaluator
leaving the domain while its peer is stopped can block in the middleware's clean-up — seen once,
60 s).

Fuzzed inputs (in this process, each with a 20 s alarm), from the shipped files mutated by the
same generator: scenario YAML (``load_scenario_config`` + ``build_scenario``), OpenDRIVE maps
(``load_road``), bags (``evaluate.py``), HighD recordings (``load_recording``) and CLI values
(``run_scenario.py``, ``evaluate.py``, ``replay.py``, ``export_highd.py``). Each must end in
success or a one-line error (``InputError`` / exit 2), never a traceback or a hang.
"""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path

from evoscen_contract.contract import GRAPH_EXIT_STATUSES, TOPIC_WORLD
from evoscen_sim.errors import InputError

from evoscen_experiments.fault_runs import END_LIMIT_S, HANG_S, GraphResult, kill_leftovers, stderr_tail, world_steps

NODES = {"sim": "evoscen_sim.nodes.sim_node", "bv_competitive": "evoscen_bv.bv_node", "bv_mutual": "evoscen_bv.bv_node",
         "bv_cooperative": "evoscen_bv.bv_node", "sut": "evoscen_sut.sut_node", "eval": "evoscen_eval.eval_node"}
"""The nodes of the default graph by class name: the BV nodes are those of ``bvs.nodes: by_policy``
(docs/architecture.md §5, "BV nodes"), one program each under its own node name."""
HOST_FAULTS = ("enospc", "readonly", "vanish", "driver-kill")
"""The fault classes that are faults of the host (:func:`evoscen_experiments.host_faults.host_run`)."""


def fault_classes() -> list[tuple]:
    """Every fault class, in the order the campaign takes them."""
    kills = [("kill", sig, node, phase) for phase in ("lockstep", "startup") for node in NODES
             for sig in ("SIGKILL", "SIGTERM")]
    host = [(kind, runner) for kind in ("enospc", "readonly") for runner in ("inline", "process", "graph")]
    return kills + [("stall",), ("inject",)] + host + [("vanish", "process"), ("driver-kill",)]


def class_name(fault: tuple) -> str:
    """A fault class as the command line names it, e.g. ``kill:SIGKILL:eval:lockstep``, ``stall``."""
    return ":".join(fault)


def _children(launcher: subprocess.Popen, module: str, node: str = "") -> list[int]:
    """The launcher's children running ``module`` (a BV node: the one named ``evoscen_<node>``)."""
    pattern = (rf"\s__node:=evoscen_{re.escape(node)}(\s|$)" if node.startswith("bv_")
               else rf"\s-m {re.escape(module)}(\s|$)")
    out = subprocess.run(["pgrep", "-P", str(launcher.pid), "-f", pattern],
                         capture_output=True, text=True, check=False).stdout
    return [int(p) for p in out.split()]


def _fault_events(bag: Path) -> list[tuple[str, str]] | None:
    """``(kind, controller)`` of every ``fault`` event of the bag, in order; None if unreadable."""
    from diagnostic_msgs.msg import DiagnosticArray
    from evoscen_contract.contract import EVENT_FAULT, TOPIC_EVENTS
    from evoscen_contract.topics import parse_events
    from evoscen_record.bag_reader import open_bag_reader
    from rclpy.serialization import deserialize_message

    try:
        return [(ev.get("kind", ""), ev.get("controller", "")) for topic, _type, _t, d in open_bag_reader(bag)
                if topic == TOPIC_EVENTS for ev in parse_events(deserialize_message(d, DiagnosticArray))
                if ev["name"] == EVENT_FAULT]
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None


def expected_kill_statuses(fault: tuple) -> tuple[int, ...]:
    """The exit statuses a kill class may end with (docs/recording.md, "Endings and exit statuses")."""
    _, sig, node, phase = fault
    if node == "sim" and sig == "SIGTERM":  # the simulation ends the run as interrupted
        return (130,) if phase == "lockstep" else (4, 130)  # start-up: before its handler is installed, a death
    return (4,)


def _world_bytes(bag: Path) -> list[bytes]:
    from evoscen_record.bag_reader import open_bag_reader

    return [d for topic, _type, _t, d in open_bag_reader(bag) if topic == TOPIC_WORLD]


def graph_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, clean_world: dict,
              max_stall_s: float = 30.0, *, repo: Path) -> GraphResult:
    """One graph run with ``fault`` on a domain this process reserves for it (the intruder joins
    it too); see the module docstring."""
    from evoscen_bringup.domains import reserve_domain, reserved_by_caller_env

    rng.randint(101, 200)  # was the domain (now reserved): drawn still, so later draws stay those of before
    with reserve_domain(None) as domain:
        return _graph_run(fault, seed, steps, rng, work, clean_world, max_stall_s, domain,
                          dict(os.environ, **reserved_by_caller_env(domain)), repo)


def _kill(fault: tuple, launcher: subprocess.Popen, rng: random.Random, running: Callable[[], bool],
          problems: list[str]) -> float | None:
    """Signal the node of a kill class at its phase; the time of the signal (None: no process to signal)."""
    _, sig, node, phase = fault
    if phase == "startup":
        end = time.monotonic() + 60
        while not _children(launcher, NODES[node], node) and time.monotonic() < end and launcher.poll() is None:
            time.sleep(0.02)
        time.sleep(rng.uniform(0.0, 1.0))
    elif running():
        time.sleep(rng.uniform(0.0, 1.0))
    pids = _children(launcher, NODES[node], node)
    sim = _children(launcher, NODES["sim"]) if (node == "eval" and phase == "lockstep" and sig == "SIGKILL") else []
    if pids and sim:
        # the evaluator: freeze the lockstep first, so that every state published reached it
        # before the signal; the steps published are then the lockstep's count less the one
        # or two it makes after SIGCONT before the launcher's stop takes effect
        os.kill(sim[0], signal.SIGSTOP)
        time.sleep(0.3)
        os.kill(pids[0], getattr(signal, sig))
        t_fault = time.monotonic()
        end = time.monotonic() + 10
        while _children(launcher, NODES["eval"]) and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.3)
        os.kill(sim[0], signal.SIGCONT)
        return t_fault
    if pids:
        os.kill(pids[0], getattr(signal, sig))
        return time.monotonic()
    problems.append(f"no {node} process to signal")
    return None


def _inject(fault: tuple, launcher: subprocess.Popen, rng: random.Random, running: Callable[[], bool],
            max_stall_s: float, domain: int, repo: Path, problems: list[str]) -> tuple[float | None, object]:
    """The fault of a graph run: a kill, a stall of the evaluator, or the intruder started on the domain.
    Returns the time of the fault (None: none or no time) and the intruder's process (None: none)."""
    kind = fault[0]
    if kind == "kill":
        return _kill(fault, launcher, rng, running, problems), None
    if kind == "stall":
        if running():
            time.sleep(rng.uniform(0.0, 1.0))
            pids = _children(launcher, NODES["eval"])
            if pids:
                os.kill(pids[0], signal.SIGSTOP)
                time.sleep(rng.uniform(2.0, max(max_stall_s, 2.0)))
                os.kill(pids[0], signal.SIGCONT)
                return time.monotonic(), None
        return None, None
    if kind == "inject":
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                   RMW_IMPLEMENTATION="rmw_fastrtps_cpp", PYTHONPATH=os.pathsep.join(sys.path))
        return None, subprocess.Popen([sys.executable, str(repo / "tests" / "wire_intruder.py"), "60"], cwd=repo,
                                      env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return None, None


def _end_intruder(intruder: subprocess.Popen, steps: int, problems: list[str]) -> None:
    """Wait for the intruder (it ends 3 s after the last world message it saw); it must have attacked at
    least half of the world messages."""
    try:
        intruder_out, intruder_err = intruder.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        intruder.kill()
        intruder_out, intruder_err = intruder.communicate()
    if "Traceback" in intruder_err:
        problems.append("the intruder itself failed")
    m = re.search(r"for (\d+) world messages", intruder_out)
    if m is None:
        problems.append("the intruder printed no count of the world messages it attacked")
    elif int(m.group(1)) < steps // 2:
        problems.append(f"the intruder attacked {m.group(1)} world messages of {steps + 1} (expected at least half)")


def _bag_figures(fault: tuple, bag: Path, node_logs: str, seed: int, steps: int, work: Path, clean_world: dict) -> tuple:
    """What a graph run's bag holds (after reindex if it has to): readable (None: no bag), reindexed, steps
    lost (gaps and the published states missing at its end: the simulation's count in ``node_logs``), the
    world identical to a clean in-process run's (inject only; else None) and its ``fault`` events."""
    readable, reindexed, lost, identical, fault_events = None, False, None, None, None
    if not bag.exists():
        return readable, reindexed, lost, identical, fault_events
    world = world_steps(bag)
    if world is None:
        import contextlib

        from evoscen_record.reindex import reindex_bag

        with contextlib.suppress(Exception):
            reindex_bag(bag, keep_original=False)
            reindexed = True
        world = world_steps(bag)
    readable = world is not None
    if readable:
        fault_events = _fault_events(bag)
    if world:
        m = re.search(r"evoscen_sim: lockstep: (\d+) steps", node_logs)
        published = int(m.group(1)) + 1 if m else None  # states 0..K
        gaps = (world[-1] + 1) - len(world)
        tail = max(published - len(world) - gaps, 0) if published is not None else 0
        if fault[0] == "kill" and fault[2] == "eval" and fault[1] == "SIGTERM":
            tail = 0  # it wrote all it had received; what came after it ended was never sent to it
        lost = gaps + tail
    elif world == []:
        lost = 0
    if fault[0] == "inject" and readable:
        if seed not in clean_world:
            from evoscen_bringup.inprocess import run_inprocess
            from evoscen_sim.config.scenario_config import load_scenario_config

            cfg = load_scenario_config(None, {"steps": steps, "seed": seed})
            run_inprocess(cfg, bag_dir=work / f"clean-{seed}" / "bag", evaluate=False)
            clean_world[seed] = _world_bytes(work / f"clean-{seed}" / "bag")
        identical = _world_bytes(bag) == clean_world[seed]
    return readable, reindexed, lost, identical, fault_events


def _kill_problems(fault: tuple, status: int, stderr: str, fault_events, reindexed: bool, problems: list[str]) -> None:
    """A kill class's ending checked: its status, the launcher's line naming the node and, for a
    controller killed in the lockstep, the one error line and the abort in the finished bag."""
    expected = expected_kill_statuses(fault)
    if status not in expected:
        problems.append(f"exit status {status}, expected {' or '.join(map(str, expected))}")
    node = f"evoscen_{fault[2]}"
    errors = [ln for ln in stderr.splitlines() if ln.startswith("error:")]
    if status == 4 and not any(ln.startswith(f"error: graph: node {node} ") for ln in errors):
        problems.append(f"no launcher's error line naming {node}")
    if status == 4 and fault[3] == "lockstep" and fault[2] not in ("sim", "eval"):
        # a controller killed in the lockstep: the launcher's line is the one error line, and the
        # simulation's abort (its consequence) is in the finished bag, naming it
        if len(errors) != 1:
            problems.append(f"{len(errors)} error lines, expected the launcher's one")
        if fault_events is None or ("abort", node) not in fault_events:
            problems.append(f"no fault event of kind abort naming {node} in the bag")
        if reindexed:
            problems.append("the bag was not finished (it needed reindex)")


def _graph_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, clean_world: dict,
               max_stall_s: float, domain: int, launcher_env: dict[str, str], repo: Path) -> GraphResult:
    out = work / f"run-{seed}"
    args = [sys.executable, str(repo / "scripts" / "run_scenario.py"), "--mode", "graph", "--steps", str(steps),
            "--seed", str(seed), "--out", str(out), "--no-plots", "--deadline", "0.5", "--max-misses", "3",
            "--domain-id", str(domain), "--overwrite"]
    if fault[0] == "inject":  # step 0 waits until the intruder's subscription is matched: it attacks every step
        args += ["--wait-for", "intruder"]
    launcher = subprocess.Popen(args, cwd=repo, env=launcher_env, text=True, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)
    intruder = None
    kind = fault[0]
    problems: list[str] = []
    mcap = out / "bag" / "bag_0.mcap"

    def running(timeout: float = 90.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end and launcher.poll() is None:
            if mcap.exists() and mcap.stat().st_size > 0:
                return True
            time.sleep(0.05)
        return False

    try:
        t_fault, intruder = _inject(fault, launcher, rng, running, max_stall_s, domain, repo, problems)
        try:
            stdout, stderr = launcher.communicate(timeout=HANG_S)
            hang = False
        except subprocess.TimeoutExpired:
            launcher.kill()
            stdout, stderr = launcher.communicate()
            hang = True
        end_s = time.monotonic() - t_fault if t_fault is not None else None
    finally:
        if launcher.poll() is None:
            launcher.kill()
            launcher.wait()
        orphans = kill_leftovers(str(out))  # a node process of the run (its parameter file is under OUT) left running
        if intruder is not None:
            _end_intruder(intruder, steps, problems)
    status = launcher.returncode if not hang else None
    # the nodes' own output is in their log files (OUT/logs/<node>.log), the terminal holds the launcher's
    node_logs = "\n".join(p.read_text(encoding="utf-8", errors="replace") for p in sorted((out / "logs").glob("*.log")))
    traceback = "Traceback" in stderr or "Traceback" in node_logs
    readable, reindexed, lost, identical, fault_events = _bag_figures(fault, out / "bag", node_logs, seed, steps, work,
                                                                      clean_world)
    allowed_loss = 0
    if kind == "kill" and fault[2] == "eval" and fault[3] == "lockstep":
        # the open chunk (<= 1 s = 10 steps) at a SIGKILL; the steps after SIGCONT (above) either way
        # what this count can see: the open chunk (10 steps) + the run-on after SIGCONT, which the
        # flow control bounds to its window (50 steps) when the stop signal is acted on late
        allowed_loss = 10 + 50 + 2 if fault[1] == "SIGKILL" else 0
    if hang:
        problems.append("hang")
    if status is not None and status not in GRAPH_EXIT_STATUSES:
        problems.append(f"exit status {status} not documented")
    if traceback:
        problems.append("traceback")
    if readable is False:
        problems.append("bag unreadable after reindex")
    if lost is not None and lost > allowed_loss:
        problems.append(f"{lost} steps lost (allowed {allowed_loss})")
    if end_s is not None and kind == "kill" and end_s > END_LIMIT_S:
        problems.append(f"ended {end_s:.1f} s after the fault")
    if identical is False:
        problems.append("world table differs from the clean run")
    if kind == "kill" and status is not None:
        _kill_problems(fault, status, stderr, fault_events, reindexed, problems)
    if kind == "inject" and status != 0:
        problems.append(f"attacked run ended {status}, not 0")
    if orphans:
        problems.append(f"{orphans} processes of the run left running")
    tail = stderr_tail(stderr, problems)
    if problems:  # what the launcher saw, and when, and how the simulation ended: why, in the campaign's output
        tail += "".join(_log_tail(out / "logs" / name, keep) for name, keep in (("launcher.log", 20),
                                                                                ("evoscen_sim.log", 4)))
    shutil.rmtree(out, ignore_errors=True)
    return GraphResult(" ".join(fault), seed, status, end_s, hang, traceback, readable, reindexed, lost, identical,
                       problems, tail, orphans)


def _log_tail(path: Path, keep: int) -> str:
    """The last ``keep`` lines of a node's log (for a run with a problem), headed by its name; '' if none."""
    try:
        lines = path.read_text(encoding="utf-8", errors="replace").strip().splitlines()[-keep:]
    except OSError:
        return ""
    return f"\n{path.name}:\n" + "\n".join(lines)


def chosen_classes(text: str | None) -> list[tuple]:
    """``--classes``: the fault classes named, comma-separated (None: every class, in turn)."""
    classes = fault_classes()
    if text is None:
        return classes
    known = {class_name(c): c for c in classes}
    wanted = [c.strip() for c in text.split(",") if c.strip()]
    if any(c not in known for c in wanted) or not wanted:
        raise InputError(f"--classes = {text!r}: expected comma-separated names among {', '.join(known)}")
    return [known[c] for c in wanted]


def summary_rows(graph: list[GraphResult], fuzzed: list[dict]) -> list[tuple[str, object]]:
    """The summary table's rows: the graph runs' figures, then the fuzzed inputs' outcomes."""
    ends = [r.end_s for r in graph if r.end_s is not None and r.fault.startswith("kill")]
    return [
        ("graph runs", len(graph)),
        ("  hangs", sum(r.hang for r in graph)),
        ("  tracebacks", sum(r.traceback for r in graph)),
        ("  undocumented exit statuses", sum(r.status is not None and r.status not in GRAPH_EXIT_STATUSES for r in graph)),
        ("  exit statuses seen", " ".join(f"{s}:{n}" for s, n in sorted(
            {s: sum(r.status == s for r in graph) for s in {r.status for r in graph}}.items(), key=str))),
        ("  bags written", sum(r.bag_readable is not None for r in graph)),
        ("  bags unreadable after reindex", sum(r.bag_readable is False for r in graph)),
        ("  bags that needed reindex", sum(r.reindexed for r in graph)),
        ("  steps lost beyond the allowance", sum(any("steps lost" in p or "runs missing" in p for p in r.problems)
                                                  for r in graph)),
        ("  orphan processes", sum(r.orphans for r in graph)),
        ("  slowest end after a kill (s)", f"{max(ends):.1f}" if ends else "-"),
        ("  attacked runs with a different world", sum(r.world_identical is False for r in graph)),
        ("  runs with a problem", sum(bool(r.problems) for r in graph)),
        ("fuzzed inputs", len(fuzzed)),
        ("  loaded, or a CLI exit 0/2", sum(f["outcome"] == "ok" for f in fuzzed)),
        ("  one-line InputError / usage error", sum(f["outcome"] == "error" for f in fuzzed)),
        ("  tracebacks", sum(f["outcome"] == "traceback" for f in fuzzed)),
        ("  hangs", sum(f["outcome"] == "hang" for f in fuzzed)),
        ("  other (multi-line error, bad exit)", sum(f["outcome"] in ("multi-line-error", "bad-exit") for f in fuzzed)),
    ]


def run_campaign(*, graph_runs: int, fuzz_inputs: int, steps: int, seed: int, classes: str | None, max_stall_s: float,
                 out: Path | None, json_path: Path | None, repo: Path,
                 clis: Callable[[], Mapping[str, Callable[[list[str]], int]]]) -> int:
    """The campaign (module docstring) in ``out`` (None: a temporary directory, removed), with the scripts
    of the checkout ``repo``; ``clis()`` gives the command lines the fuzzing calls
    (:data:`evoscen_experiments.input_fuzz.CLIS`). Returns 0 when every acceptance figure holds, else 1."""
    import numpy as np

    from evoscen_experiments.host_faults import host_run
    from evoscen_experiments.input_fuzz import fuzz

    for name, value, low in (("--graph-runs", graph_runs, 0), ("--fuzz", fuzz_inputs, 0), ("--steps", steps, 50)):
        if value < low or value > 100_000:
            raise InputError(f"{name} = {value}: expected an integer in [{low}, 100000]")
    chosen = chosen_classes(classes)
    if not 2.0 <= max_stall_s <= 60.0:
        raise InputError(f"--max-stall = {max_stall_s}: expected a number in [2, 60] (s)")
    work = Path(tempfile.mkdtemp(prefix="evoscen-faults-")) if out is None else out
    work.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    graph: list[GraphResult] = []
    clean_world: dict = {}
    try:
        for i in range(graph_runs):
            fault = chosen[i % len(chosen)]
            if fault[0] in HOST_FAULTS:
                r = host_run(fault, 1000 + i, steps, rng, work, repo)
            else:
                r = graph_run(fault, 1000 + i, steps, rng, work, clean_world, max_stall_s, repo=repo)
            graph.append(r)
            print(f"graph {i + 1}/{graph_runs} [{r.fault}]: status {r.status}, "
                  f"end {'-' if r.end_s is None else f'{r.end_s:.1f} s'}, lost {r.steps_lost}"
                  + (f", world identical {r.world_identical}" if r.world_identical is not None else "")
                  + (f"  PROBLEMS: {'; '.join(r.problems)}" if r.problems else ""), flush=True)
            if r.problems and r.stderr_tail:
                print("    " + r.stderr_tail.strip().replace("\n", "\n    "), flush=True)
        fuzzed = fuzz(fuzz_inputs, np.random.default_rng(seed), work, clis()) if fuzz_inputs else []
    finally:
        if out is None:
            shutil.rmtree(work, ignore_errors=True)
    for f in fuzzed:
        if f["outcome"] not in ("ok", "error"):
            print(f"fuzz {f['case']} [{f['kind']}]: {f['outcome']}: {f['detail']}")
    rows = summary_rows(graph, fuzzed)
    width = max(len(k) for k, _ in rows)
    print("\n" + "\n".join(f"{k.ljust(width)}  {v}" for k, v in rows))
    if json_path:
        json_path.write_text(json.dumps({"graph": [asdict(r) for r in graph], "fuzz": fuzzed}, indent=1))
    ok = not any(r.problems for r in graph) and all(f["outcome"] in ("ok", "error") for f in fuzzed)
    print("campaign: " + ("every figure holds" if ok else "PROBLEMS found (above)"))
    return 0 if ok else 1
