#!/usr/bin/env python3
"""Fault-and-fuzz campaign: kills, stalls and hostile messages in node graphs; fuzzed inputs.

    python scripts/fault_campaign.py [--graph-runs N] [--fuzz N] [--steps S] [--seed SEED]
                                     [--classes C,C,...] [--max-stall S] [--out DIR] [--json FILE]

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

Prints one line per run and the summary table; exit 0 when every acceptance figure holds, 1 if
not, 2 on bad arguments. Full size (issue 16): ``--graph-runs 100 --fuzz 300``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
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
from dataclasses import asdict, dataclass, field
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
import numpy as np
from evoscen_contract.contract import EXIT_BAD_INPUT, GRAPH_EXIT_STATUSES, TOPIC_WORLD

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "scripts"
NODES = {"sim": "evoscen_sim.sim_node", "bv_competitive": "evoscen_bv.bv_node", "bv_mutual": "evoscen_bv.bv_node",
         "bv_cooperative": "evoscen_bv.bv_node", "sut": "evoscen_sut.sut_node", "eval": "evoscen_eval.eval_node"}
"""The nodes of the default graph by class name: the BV nodes are those of ``bvs.nodes: by_policy``
(docs/architecture.md §5, "BV nodes"), one program each under its own node name."""
END_LIMIT_S = 10.0
HANG_S = 120.0
DT_NS = 100_000_000


@dataclass
class GraphResult:
    fault: str
    seed: int
    status: int | None
    end_s: float | None
    hang: bool
    traceback: bool
    bag_readable: bool | None  # None: no bag was started (a death during start-up)
    reindexed: bool
    steps_lost: int | None
    world_identical: bool | None = None
    problems: list[str] = field(default_factory=list)
    stderr_tail: str = ""  # the launcher's last lines, kept for runs with a problem
    orphans: int = 0  # processes of the run left running after it ended (driver-kill: after the resume)


def _fault_classes() -> list[tuple]:
    kills = [("kill", sig, node, phase) for phase in ("lockstep", "startup") for node in NODES
             for sig in ("SIGKILL", "SIGTERM")]
    host = [(kind, runner) for kind in ("enospc", "readonly") for runner in ("inline", "process", "graph")]
    return kills + [("stall",), ("inject",)] + host + [("vanish", "process"), ("driver-kill",)]


HOST_FAULT_STATUS = 5  # evoscen_contract.contract.EXIT_HOST_FAULT


def _mount_tmpfs(path: Path, size_kib: int) -> str | None:
    """Mount a tmpfs of ``size_kib`` KiB at ``path``; None, or why it could not."""
    path.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(path)],
                       capture_output=True, text=True, check=False)
    return None if r.returncode == 0 else f"cannot mount a tmpfs (root needed): {r.stderr.strip()}"


READ_ONLY_IMAGE_MIB = 64


def mount_ext4(path: Path, image: Path, size_mib: int = READ_ONLY_IMAGE_MIB) -> str | None:
    """An ext4 file system of ``size_mib`` MiB in the file ``image`` (sparse), mounted at ``path`` on
    a loop device with ``errors=remount-ro``; None, or why it could not."""
    path.mkdir(parents=True, exist_ok=True)
    with open(image, "wb") as f:
        f.truncate(size_mib << 20)
    r = subprocess.run(["mkfs.ext4", "-q", "-F", str(image)], capture_output=True, text=True, check=False)
    if r.returncode != 0:
        return f"cannot make an ext4 file system in {image}: {r.stderr.strip()}"
    r = subprocess.run(["mount", "-o", "loop,errors=remount-ro", str(image), str(path)],
                       capture_output=True, text=True, check=False)
    return None if r.returncode == 0 else f"cannot mount {image} (root and a loop device needed): {r.stderr.strip()}"


def make_read_only(path: Path) -> str | None:
    """Make the ext4 file system mounted at ``path`` read-only now, files open for writing and all,
    as the kernel does on an I/O error under ``errors=remount-ro`` (``/sys/fs/ext4/DEV/trigger_fs_error``);
    None, or why it could not."""
    where = os.path.realpath(path)
    devs = [ln.split()[0] for ln in Path("/proc/mounts").read_text().splitlines() if ln.split()[1] == where]
    if not devs:
        return f"{where} is not a mount point"
    try:
        Path(f"/sys/fs/ext4/{Path(devs[-1]).name}/trigger_fs_error").write_text("fault campaign: read-only\n")
    except OSError as exc:
        return f"cannot make {where} read-only: {exc}"
    return None


def _check_host_fault_end(stderr: str, status: int | None, problems: list[str]) -> str | None:
    """The one ``error:`` line of a run ended by a fault of the host (problems noted); None if none."""
    errors = [ln for ln in stderr.splitlines() if ln.startswith("error:")]
    if status not in (0, HOST_FAULT_STATUS):
        problems.append(f"exit status {status}, expected {HOST_FAULT_STATUS} (or 0 if everything fit)")
    if status == HOST_FAULT_STATUS and len(errors) != 1:
        problems.append(f"{len(errors)} error lines, expected one")
    return errors[0] if errors else None


def host_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path) -> GraphResult:
    """One run with a fault of the host (module docstring): a full disk, the output removed, the
    campaign driver killed."""
    kind = fault[0]
    problems: list[str] = []
    status, hang, stderr, end_s = None, False, "", None
    readable, reindexed, lost, orphans = None, False, None, 0
    if kind == "driver-kill":
        return _driver_kill(fault, seed, steps, rng, work)
    out_root = work / f"host-{seed}"
    mounted = False
    if kind == "enospc":
        size = rng.randint(150, 1500)  # KiB: the disk fills at a random step
        why = _mount_tmpfs(out_root, size)
        if why is not None:
            problems.append(why)
            return GraphResult(" ".join(fault), seed, None, None, False, False, None, False, None, problems=problems)
        mounted = True
    elif kind == "readonly":
        why = mount_ext4(out_root, work / f"host-{seed}.img")
        if why is not None:
            problems.append(why)
            (work / f"host-{seed}.img").unlink(missing_ok=True)
            return GraphResult(" ".join(fault), seed, None, None, False, False, None, False, None, problems=problems)
        mounted = True
    out = out_root / "run"
    runner = fault[1]
    args = [sys.executable, str(SCRIPTS / "run_scenario.py"), "--steps", str(steps), "--seed", str(seed),
            "--out", str(out), "--no-plots"]
    args += ["--mode", "graph"] if runner == "graph" else ["--mode", "inprocess", "--quiet", "--bag-writer", runner]
    try:
        proc = subprocess.Popen(args, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        if kind == "vanish":
            mcap, at = out / "bag" / "bag_0.mcap", rng.randint(20_000, 400_000)
            end = time.monotonic() + 60
            while proc.poll() is None and time.monotonic() < end and not (mcap.exists() and mcap.stat().st_size > at):
                time.sleep(0.01)
            shutil.rmtree(out, ignore_errors=True)
            t_fault = time.monotonic()
        elif kind == "readonly":
            mcap, at = out / "bag" / "bag_0.mcap", rng.randint(20_000, 400_000)
            end = time.monotonic() + 90
            while proc.poll() is None and time.monotonic() < end and not (mcap.exists() and mcap.stat().st_size > at):
                time.sleep(0.01)
            if proc.poll() is not None:
                problems.append("the run ended before its output was made read-only")
            why = make_read_only(out_root)
            if why is not None:
                problems.append(why)
            t_fault = time.monotonic()
        try:
            _stdout, stderr = proc.communicate(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            _stdout, stderr = proc.communicate()
            hang = True
        if kind in ("vanish", "readonly"):
            end_s = time.monotonic() - t_fault
        status = None if hang else proc.returncode
        line = _check_host_fault_end(stderr, status, problems)
        bag = out / "bag"
        if kind == "readonly" and status == HOST_FAULT_STATUS and line is not None and not (
                line.startswith(f"error: {'evoscen_eval: ' if runner == 'graph' else ''}cannot write "
                                f"{bag / 'bag_0.mcap'}: Read-only file system (EROFS)")):
            problems.append("the line does not name the bag file and EROFS")
        if kind == "readonly" and status != HOST_FAULT_STATUS:
            problems.append(f"exit status {status}, expected {HOST_FAULT_STATUS}")
        if kind == "readonly" and end_s is not None and end_s > END_LIMIT_S:
            problems.append(f"ended {end_s:.1f} s after the fault")
        if kind in ("enospc", "readonly") and bag.is_dir():
            copy = work / f"host-{seed}-bag"
            shutil.copytree(bag, copy)
            world = _world_steps(copy)
            if world is None:
                from evoscen_record.reindex import reindex_bag

                with contextlib.suppress(Exception):
                    reindex_bag(copy, keep_original=False)
                    reindexed = True
                world = _world_steps(copy)
            shutil.rmtree(copy, ignore_errors=True)
            readable = world is not None
            if world is not None:
                gaps = (world[-1] + 1 - len(world)) if world else 0
                m = re.search(r"the (\d+) world states", line or "")
                stated = int(m.group(1)) if m else None
                if status == HOST_FAULT_STATUS and stated is None:
                    problems.append("the error line does not say how many world states the bag holds")
                lost = gaps + (abs(stated - len(world)) if stated is not None else 0)
                if line and "reindex.py" in line and not reindexed:
                    problems.append("the line asks for reindex.py, but the bag was finished")
        elif kind == "vanish" and status == HOST_FAULT_STATUS and line and "is gone" not in line:
            problems.append("the line does not say the bag is gone")
    finally:
        for pid in subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True).stdout.split():
            orphans += 1
            with contextlib.suppress(OSError):
                os.kill(int(pid), signal.SIGKILL)
        if mounted:
            subprocess.run(["umount", "-l", str(out_root)], check=False)  # a loop device is freed with it
        shutil.rmtree(out_root, ignore_errors=True)
        (work / f"host-{seed}.img").unlink(missing_ok=True)
    traceback = "Traceback" in stderr
    if hang:
        problems.append("hang")
    if traceback:
        problems.append("traceback")
    if readable is False:
        problems.append("bag unreadable after reindex")
    if lost:
        problems.append(f"{lost} steps lost (allowed 0 beyond the states the line names)")
    if orphans:
        problems.append(f"{orphans} processes of the run left running")
    tail = "\n".join(stderr.strip().splitlines()[-12:]) if problems else ""
    return GraphResult(" ".join(fault), seed, status, end_s, hang, traceback, readable, reindexed, lost,
                       orphans=orphans, problems=problems, stderr_tail=tail)


def _driver_kill(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path) -> GraphResult:
    """A campaign whose driver is SIGKILLed mid-run (its process alone), then the same command: it
    must end the killed driver's Ray processes, and every run must be done exactly once."""
    import pyarrow.parquet as pq

    from evoscen_bringup.ray_leftovers import DRIVER_FILE, session_processes, zombie

    problems: list[str] = []
    camp = work / f"campaign-{seed}"
    camp.mkdir(parents=True, exist_ok=True)
    spec = camp / "spec.yaml"
    n_seeds = 4
    spec.write_text(f"name: faults\nsteps: {min(steps, 600)}\nseeds: {{first: {seed}, count: {n_seeds}}}\n"
                    "grid:\n  sut.model: [mobil, level0]\n", encoding="utf-8")
    out = camp / "out"
    cmd = [sys.executable, str(SCRIPTS / "campaign.py"), str(spec), "--out", str(out), "--cpus", "2"]
    first = subprocess.Popen(cmd, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
    session, hang, status, stderr, orphans, lost = None, False, None, "", 0, None
    try:
        end = time.monotonic() + HANG_S
        while time.monotonic() < end and first.poll() is None and not (
                (out / DRIVER_FILE).exists() and list((out / "runs").glob("*/result.json"))):
            time.sleep(0.05)
        if (out / DRIVER_FILE).exists():
            session = json.loads((out / DRIVER_FILE).read_text())["session_dir"]
        time.sleep(rng.uniform(0.0, 1.0))
        if first.poll() is None:
            os.kill(first.pid, signal.SIGKILL)  # the driver only
        first.communicate(timeout=30)
        again = subprocess.Popen(cmd, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 start_new_session=True)
        try:
            _stdout, stderr = again.communicate(timeout=HANG_S * 2)
            status = again.returncode
        except subprocess.TimeoutExpired:
            os.killpg(again.pid, signal.SIGKILL)
            _stdout, stderr = again.communicate()
            hang = True
        if session is not None:
            alive = [p for p, _ in session_processes(session) if not zombie(p)]
            orphans = len(alive)
            for p in alive:
                with contextlib.suppress(OSError):
                    os.kill(p, signal.SIGKILL)
        if status == 0:
            keys = [row["key"] for row in pq.read_table(out / "results.parquet").to_pylist()]
            if len(keys) != len(set(keys)):
                problems.append("a run counted twice")
            lost = 2 * n_seeds - len(set(keys))
    finally:
        for p in (first,):
            if p.poll() is None:
                p.kill()
        shutil.rmtree(camp, ignore_errors=True)
    if status != 0 and not hang:
        problems.append(f"the resumed campaign ended {status}, not 0")
    if hang:
        problems.append("hang")
    if "Traceback" in stderr:
        problems.append("traceback")
    if lost:
        problems.append(f"{lost} runs missing after the resume")
    if orphans:
        problems.append(f"{orphans} Ray processes of the killed driver left running")
    tail = "\n".join(stderr.strip().splitlines()[-12:]) if problems else ""
    return GraphResult(" ".join(fault), seed, status, None, hang, "Traceback" in stderr, None, False, lost,
                       orphans=orphans, problems=problems, stderr_tail=tail)


def _children(launcher: subprocess.Popen, module: str, node: str = "") -> list[int]:
    """The launcher's children running ``module`` (a BV node: the one named ``evoscen_<node>``)."""
    pattern = (rf"\s__node:=evoscen_{re.escape(node)}(\s|$)" if node.startswith("bv_")
               else rf"\s-m {re.escape(module)}(\s|$)")
    out = subprocess.run(["pgrep", "-P", str(launcher.pid), "-f", pattern],
                         capture_output=True, text=True, check=False).stdout
    return [int(p) for p in out.split()]


def _world_steps(bag: Path) -> list[int] | None:
    from evoscen_record.bag_reader import open_bag_reader

    try:
        return sorted({t // DT_NS for topic, _type, t, _d in open_bag_reader(bag) if topic == TOPIC_WORLD})
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None


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


def class_name(fault: tuple) -> str:
    """A fault class as the command line names it, e.g. ``kill:SIGKILL:eval:lockstep``, ``stall``."""
    return ":".join(fault)


def graph_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, clean_world: dict,
              max_stall_s: float = 30.0) -> GraphResult:
    """One graph run with ``fault`` on a domain this process reserves for it (the intruder joins
    it too); see the module docstring."""
    from evoscen_bringup.domains import reserve_domain, reserved_by_caller_env

    rng.randint(101, 200)  # was the domain (now reserved): drawn still, so later draws stay those of before
    with reserve_domain(None) as domain:
        return _graph_run(fault, seed, steps, rng, work, clean_world, max_stall_s, domain,
                          dict(os.environ, **reserved_by_caller_env(domain)))


def _graph_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, clean_world: dict,
               max_stall_s: float, domain: int, launcher_env: dict[str, str]) -> GraphResult:
    out = work / f"run-{seed}"
    args = [sys.executable, str(SCRIPTS / "run_scenario.py"), "--mode", "graph", "--steps", str(steps),
            "--seed", str(seed), "--out", str(out), "--no-plots", "--deadline", "0.5", "--max-misses", "3",
            "--domain-id", str(domain), "--overwrite"]
    if fault[0] == "inject":  # step 0 waits until the intruder's subscription is matched: it attacks every step
        args += ["--wait-for", "intruder"]
    launcher = subprocess.Popen(args, cwd=REPO, env=launcher_env, text=True, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE)
    intruder = None
    t_fault = None
    kind = fault[0]
    problems: list[str] = []
    orphans = 0
    mcap = out / "bag" / "bag_0.mcap"

    def running(timeout: float = 90.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end and launcher.poll() is None:
            if mcap.exists() and mcap.stat().st_size > 0:
                return True
            time.sleep(0.05)
        return False

    try:
        if kind == "kill":
            _, sig, node, phase = fault
            if phase == "startup":
                end = time.monotonic() + 60
                while not _children(launcher, NODES[node], node) and time.monotonic() < end and launcher.poll() is None:
                    time.sleep(0.02)
                time.sleep(rng.uniform(0.0, 1.0))
            elif running():
                time.sleep(rng.uniform(0.0, 1.0))
            pids = _children(launcher, NODES[node], node)
            sim = _children(launcher, NODES["sim"]) if (node == "eval" and phase == "lockstep"
                                                         and sig == "SIGKILL") else []
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
            elif pids:
                os.kill(pids[0], getattr(signal, sig))
                t_fault = time.monotonic()
            else:
                problems.append(f"no {node} process to signal")
        elif kind == "stall":
            if running():
                time.sleep(rng.uniform(0.0, 1.0))
                pids = _children(launcher, NODES["eval"])
                if pids:
                    os.kill(pids[0], signal.SIGSTOP)
                    time.sleep(rng.uniform(2.0, max(max_stall_s, 2.0)))
                    os.kill(pids[0], signal.SIGCONT)
                    t_fault = time.monotonic()
        elif kind == "inject":
            env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                       RMW_IMPLEMENTATION="rmw_fastrtps_cpp", PYTHONPATH=os.pathsep.join(sys.path))
            intruder = subprocess.Popen([sys.executable, str(REPO / "tests" / "wire_intruder.py"), "60"], cwd=REPO,
                                        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
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
        for pid in subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True).stdout.split():
            orphans += 1  # a node process of the run (its parameter file is under OUT) left running
            with contextlib.suppress(OSError):
                os.kill(int(pid), signal.SIGKILL)
        if intruder is not None:
            try:  # it ends 3 s after the last world message it saw
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
    status = launcher.returncode if not hang else None
    traceback = "Traceback" in stderr
    readable, reindexed, lost, identical, fault_events = None, False, None, None, None
    if (out / "bag").exists():
        world = _world_steps(out / "bag")
        if world is None:
            from evoscen_record.reindex import reindex_bag

            with contextlib.suppress(Exception):
                reindex_bag(out / "bag", keep_original=False)
                reindexed = True
            world = _world_steps(out / "bag")
        readable = world is not None
        if readable:
            fault_events = _fault_events(out / "bag")
        if world:
            m = re.search(r"evoscen_sim: lockstep: (\d+) steps", stderr)
            published = int(m.group(1)) + 1 if m else None  # states 0..K
            gaps = (world[-1] + 1) - len(world)
            tail = max(published - len(world) - gaps, 0) if published is not None else 0
            if kind == "kill" and fault[2] == "eval" and fault[1] == "SIGTERM":
                tail = 0  # it wrote all it had received; what came after it ended was never sent to it
            lost = gaps + tail
        elif world == []:
            lost = 0
        if kind == "inject" and readable:
            if seed not in clean_world:
                from evoscen_bringup.inprocess import run_inprocess
                from evoscen_sim.config import load_scenario_config

                cfg = load_scenario_config(None, {"steps": steps, "seed": seed})
                run_inprocess(cfg, bag_dir=work / f"clean-{seed}" / "bag", evaluate=False)
                clean_world[seed] = _world_bytes(work / f"clean-{seed}" / "bag")
            identical = _world_bytes(out / "bag") == clean_world[seed]
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
        expected = expected_kill_statuses(fault)
        if status not in expected:
            problems.append(f"exit status {status}, expected {' or '.join(map(str, expected))}")
        node = f"evoscen_{fault[2]}"
        errors = [ln for ln in stderr.splitlines() if ln.startswith("error:")]
        if status == 4 and not any(ln.startswith(f"error: graph: node {node} ") for ln in errors):
            problems.append(f"no launcher's error line naming {node}")
        if status == 4 and fault[3] == "lockstep" and fault[2] not in ("sim", "eval"):
            # a controller killed in the lockstep: the launcher's line is the one error line, and the
            # simulation's deadline abort (its consequence) is in the finished bag, naming it
            if len(errors) != 1:
                problems.append(f"{len(errors)} error lines, expected the launcher's one")
            if fault_events is None or ("abort", node) not in fault_events:
                problems.append(f"no fault event of kind abort naming {node} in the bag")
            if reindexed:
                problems.append("the bag was not finished (it needed reindex)")
    if kind == "inject" and status != 0:
        problems.append(f"attacked run ended {status}, not 0")
    if orphans:
        problems.append(f"{orphans} processes of the run left running")
    shutil.rmtree(out, ignore_errors=True)
    tail = "\n".join(stderr.strip().splitlines()[-12:]) if problems else ""
    return GraphResult(" ".join(fault), seed, status, end_s, hang, traceback, readable, reindexed, lost, identical,
                       problems, tail, orphans)


# --------------------------------------------------------------------------- fuzzing

class _Alarm(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Alarm


def _mutate_text(text: str, rng: np.random.Generator) -> str:
    """One hostile edit of a text file."""
    lines = text.split("\n")
    op = int(rng.integers(0, 9))
    if op == 0:  # flip bytes
        b = bytearray(text.encode("utf-8"))
        for _ in range(int(rng.integers(1, 8))):
            b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
        return b.decode("utf-8", errors="surrogateescape")
    if op == 1:  # cut short
        return text[: int(rng.integers(0, len(text)))]
    if op == 2:  # drop a line
        del lines[int(rng.integers(0, len(lines)))]
        return "\n".join(lines)
    if op == 3:  # a value replaced by a hostile token
        tokens = ["1e308", "-1", "0", "nan", "inf", "''", "[]", "{}", "0x10", "9" * 40, "!!python/object:os.system x",
                  "&a [*a, *a]", "~", "true", "\u0000", "-0.0", "1e-12"]
        i = int(rng.integers(0, len(lines)))
        if ":" in lines[i]:
            key, _, _ = lines[i].partition(":")
            lines[i] = f"{key}: {tokens[int(rng.integers(0, len(tokens)))]}"
        return "\n".join(lines)
    if op == 4:  # deep nesting
        depth = int(rng.integers(50, 5000))
        return "[" * depth + "]" * depth
    if op == 5:  # NUL bytes
        i = int(rng.integers(0, len(text)))
        return text[:i] + "\x00" + text[i:]
    if op == 6:  # duplicate a line
        i = int(rng.integers(0, len(lines)))
        lines.insert(i, lines[i])
        return "\n".join(lines)
    if op == 7:  # numbers scaled wildly
        return re.sub(r"(?<![\w.])(\d+(\.\d+)?)", lambda m: str(float(m.group(1)) * float(rng.choice([-1, 1e9, 1e-9, 0]))),
                      text, count=int(rng.integers(1, 5)))
    return text.replace(" ", "\t", int(rng.integers(1, 20)))  # tabs


def _finite_at_least(text: str, low: float) -> bool:
    """Whether ``text`` reads as a finite number >= ``low`` (Python's own float parsing)."""
    try:
        value = float(text)
    except ValueError:
        return False
    return np.isfinite(value) and value >= low


def _one_line_error(exc: BaseException) -> bool:
    return "\n" not in str(exc).strip() and bool(str(exc).strip())


def fuzz(n: int, rng: np.random.Generator, work: Path) -> list[dict]:
    """``n`` fuzzed inputs over the five input kinds; one dict per input."""
    from evoscen_bringup.inprocess import run_inprocess
    from evoscen_bringup.scenario import build_scenario
    from evoscen_eval.highd import load_recording
    from evoscen_sim.config import load_scenario_config, share_path
    from evoscen_sim.errors import InputError
    from evoscen_sim.road import DEFAULT_MAP_PATH, load_road

    default_yaml = share_path("config/default_scenario.yaml")
    yaml_text = default_yaml.read_text(encoding="utf-8")
    map_text = Path(DEFAULT_MAP_PATH).read_text(encoding="utf-8")
    base_bag = work / "fuzz-base" / "bag"
    run_inprocess(load_scenario_config(None, {"steps": 60, "seed": 1}), bag_dir=base_bag, evaluate=False)
    highd_dir = work / "fuzz-base" / "highd"
    sys.path.insert(0, str(SCRIPTS))
    import evaluate as evaluate_cli
    import export_highd as export_cli
    import replay as replay_cli
    import run_scenario as run_cli

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        export_cli.main([str(base_bag), str(highd_dir), "--recording-id", "1"])
    highd_files = sorted(highd_dir.glob("*.csv"))
    hostile = ["0x10", "1e300", "-1", "nan", "", " ", "１２", "1_000", "9" * 30, "--", "-0", "inf", "\x00", "3.5"]
    kinds = ("config", "map", "bag", "highd", "cli")
    results = []
    old = signal.signal(signal.SIGALRM, _on_alarm)
    cwd = os.getcwd()
    os.chdir(work)  # a CLI value that names the current directory writes here, not into the checkout
    try:
        for i in range(n):
            kind = kinds[i % len(kinds)]
            case = work / f"fuzz-{i}"
            case.mkdir(parents=True, exist_ok=True)
            outcome, detail = "ok", ""
            signal.alarm(20)
            sink_out, sink_err = io.StringIO(), io.StringIO()
            try:
                with contextlib.redirect_stdout(sink_out), contextlib.redirect_stderr(sink_err):
                    if kind == "config":
                        p = case / "scenario.yaml"
                        p.write_text(_mutate_text(yaml_text, rng), encoding="utf-8", errors="surrogateescape")
                        build_scenario(load_scenario_config(p, {"steps": 5}))
                    elif kind == "map":
                        p = case / "map.xodr"
                        p.write_text(_mutate_text(map_text, rng), encoding="utf-8", errors="surrogateescape")
                        load_road(p)
                    elif kind == "bag":
                        bag = case / "bag"
                        shutil.copytree(base_bag, bag)
                        target = rng.choice(sorted(bag.iterdir()))
                        data = bytearray(target.read_bytes())
                        if rng.random() < 0.5:
                            data = data[: int(rng.integers(0, len(data)))]
                        else:
                            for _ in range(int(rng.integers(1, 16))):
                                data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
                        target.write_bytes(bytes(data))
                        code = evaluate_cli.main([str(bag), "--out", str(case / "report"), "--no-plots"])
                        if code not in (0, 2):
                            outcome, detail = "bad-exit", f"evaluate.py exit {code}"
                    elif kind == "highd":
                        rec = case / "highd"
                        shutil.copytree(highd_dir, rec)
                        target = highd_files[int(rng.integers(0, len(highd_files)))].name
                        text = (rec / target).read_text(encoding="utf-8")
                        (rec / target).write_text(_mutate_text(text, rng), encoding="utf-8", errors="surrogateescape")
                        load_recording(rec, 1)
                    else:
                        tool = int(rng.integers(0, 4))
                        tok = hostile[int(rng.integers(0, len(hostile)))]
                        detail = f"tool {('run_scenario', 'evaluate', 'replay', 'export_highd')[tool]} value {tok!r}"
                        if tool == 0:
                            flag = str(rng.choice(["--steps", "--seed", "--bvs", "--mix", "--sut", "--out"]))
                            argv = ["--mode", "inprocess", "--no-record", "--quiet", "--steps", "3",
                                    "--out", str(case / "o"), flag, tok]
                            code = run_cli.main(argv)
                        elif tool == 1:
                            code = evaluate_cli.main([str(base_bag), "--out", tok or str(case / "r"), "--no-plots"])
                        elif tool == 2:
                            flag = str(rng.choice(["--rate", "--start-delay", "--wait-timeout", "--wait-subscribers"]))
                            if flag in ("--start-delay", "--wait-timeout") and _finite_at_least(tok, 10.0):
                                flag = "--rate"  # a long delay or wait that is asked for is no hang
                            code = replay_cli.main([str(base_bag), flag, tok, "--rate", "0", "--wait-timeout", "0.1"])
                        else:
                            flag = str(rng.choice(["--frame-rate", "--recording-id"]))
                            code = export_cli.main([str(base_bag), str(case / "h"), flag, tok])
                        if code not in (0, 1, 2):
                            outcome, detail = "bad-exit", f"exit {code}"
            except InputError as exc:
                outcome = "error" if _one_line_error(exc) else "multi-line-error"
                detail = str(exc)[:160]
            except SystemExit as exc:  # argparse: usage + one error line, exit 2
                outcome = "error" if exc.code == 2 else "bad-exit"
                detail = f"SystemExit {exc.code}"
            except _Alarm:
                outcome, detail = "hang", f"no end within 20 s {detail}"
            except BaseException as exc:  # noqa: BLE001 - a traceback: what the campaign looks for
                outcome, detail = "traceback", f"{type(exc).__name__}: {str(exc)[:160]}"
            finally:
                signal.alarm(0)
            if "Traceback" in sink_err.getvalue():
                outcome, detail = "traceback", sink_err.getvalue().strip().splitlines()[-1][:160]
            if outcome in ("ok", "error") and kind == "cli":
                detail = ""
            results.append({"case": i, "kind": kind, "outcome": outcome, "detail": detail})
            shutil.rmtree(case, ignore_errors=True)
    finally:
        signal.signal(signal.SIGALRM, old)
        os.chdir(cwd)
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="fault_campaign.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--graph-runs", type=int, default=len(_fault_classes()),
                    help=f"runs with a fault (default {len(_fault_classes())}: each class once)")
    ap.add_argument("--fuzz", type=int, default=50, help="fuzzed inputs (default 50)")
    ap.add_argument("--steps", type=int, default=3000, help="steps of each graph run (default 3000)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the campaign's generator (default 0)")
    ap.add_argument("--classes", default=None,
                    help="only these fault classes, comma-separated (e.g. kill:SIGKILL:eval:lockstep,stall,inject; "
                         "default: all, in turn)")
    ap.add_argument("--max-stall", type=float, default=30.0, help="longest evaluator stall in s (default 30)")
    ap.add_argument("--out", type=Path, default=None, help="working directory (default: a temporary one, removed)")
    ap.add_argument("--json", type=Path, default=None, help="also write every result as JSON here")
    args = ap.parse_args(argv)
    for name, value, low in (("--graph-runs", args.graph_runs, 0), ("--fuzz", args.fuzz, 0), ("--steps", args.steps, 50)):
        if value < low or value > 100_000:
            print(f"error: {name} = {value}: expected an integer in [{low}, 100000]", file=sys.stderr)
            return EXIT_BAD_INPUT
    classes = _fault_classes()
    if args.classes is not None:
        known = {class_name(c): c for c in classes}
        wanted = [c.strip() for c in args.classes.split(",") if c.strip()]
        bad = [c for c in wanted if c not in known]
        if bad or not wanted:
            print(f"error: --classes = {args.classes!r}: expected comma-separated names among {', '.join(known)}",
                  file=sys.stderr)
            return EXIT_BAD_INPUT
        classes = [known[c] for c in wanted]
    if not 2.0 <= args.max_stall <= 60.0:
        print(f"error: --max-stall = {args.max_stall}: expected a number in [2, 60] (s)", file=sys.stderr)
        return EXIT_BAD_INPUT
    work = Path(tempfile.mkdtemp(prefix="evoscen-faults-")) if args.out is None else args.out
    work.mkdir(parents=True, exist_ok=True)
    rng = random.Random(args.seed)
    graph: list[GraphResult] = []
    clean_world: dict = {}
    try:
        for i in range(args.graph_runs):
            fault = classes[i % len(classes)]
            if fault[0] in ("enospc", "readonly", "vanish", "driver-kill"):
                r = host_run(fault, 1000 + i, args.steps, rng, work)
            else:
                r = graph_run(fault, 1000 + i, args.steps, rng, work, clean_world, args.max_stall)
            graph.append(r)
            print(f"graph {i + 1}/{args.graph_runs} [{r.fault}]: status {r.status}, "
                  f"end {'-' if r.end_s is None else f'{r.end_s:.1f} s'}, lost {r.steps_lost}"
                  + (f", world identical {r.world_identical}" if r.world_identical is not None else "")
                  + (f"  PROBLEMS: {'; '.join(r.problems)}" if r.problems else ""), flush=True)
        fuzzed = fuzz(args.fuzz, np.random.default_rng(args.seed), work) if args.fuzz else []
    finally:
        if args.out is None:
            shutil.rmtree(work, ignore_errors=True)
    for f in fuzzed:
        if f["outcome"] not in ("ok", "error"):
            print(f"fuzz {f['case']} [{f['kind']}]: {f['outcome']}: {f['detail']}")
    ends = [r.end_s for r in graph if r.end_s is not None and r.fault.startswith("kill")]
    rows = [
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
    width = max(len(k) for k, _ in rows)
    print("\n" + "\n".join(f"{k.ljust(width)}  {v}" for k, v in rows))
    if args.json:
        args.json.write_text(json.dumps({"graph": [asdict(r) for r in graph], "fuzz": fuzzed}, indent=1))
    ok = not any(r.problems for r in graph) and all(f["outcome"] in ("ok", "error") for f in fuzzed)
    print("campaign: " + ("every figure holds" if ok else "PROBLEMS found (above)"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
