"""Faults of the host for the fault campaign (:mod:`evoscen_experiments.faults`; docs/recording.md,
"Faults of the host"): the run's output on a tmpfs that fills up, on an ext4 file system made
read-only, or removed while the bag is written, and a campaign whose driver is killed. The runs are
the scripts of the checkout ``repo`` (``scripts/run_scenario.py``, ``scripts/campaign.py``)."""

from __future__ import annotations

import contextlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from evoscen_contract.contract import EXIT_HOST_FAULT as HOST_FAULT_STATUS

from evoscen_experiments.fault_runs import END_LIMIT_S, HANG_S, GraphResult, kill_leftovers, stderr_tail, world_steps


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


def host_run(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, repo: Path) -> GraphResult:
    """One run with a fault of the host (module docstring): a full disk, the output removed, the
    campaign driver killed."""
    kind = fault[0]
    problems: list[str] = []
    status, hang, stderr, end_s = None, False, "", None
    readable, reindexed, lost, orphans = None, False, None, 0
    if kind == "driver-kill":
        return _driver_kill(fault, seed, steps, rng, work, repo)
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
    args = [sys.executable, str(repo / "scripts" / "run_scenario.py"), "--steps", str(steps), "--seed", str(seed),
            "--out", str(out), "--no-plots"]
    args += ["--mode", "graph"] if runner == "graph" else ["--mode", "inprocess", "--quiet", "--bag-writer", runner]
    try:
        proc = subprocess.Popen(args, cwd=repo, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
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
        readable, reindexed, lost = _bag_after(kind, runner, out / "bag", work / f"host-{seed}-bag", status, line,
                                               end_s, problems)
    finally:
        orphans += kill_leftovers(str(out))
        if mounted:
            subprocess.run(["umount", "-l", str(out_root)], check=False)  # a loop device is freed with it
        shutil.rmtree(out_root, ignore_errors=True)
        (work / f"host-{seed}.img").unlink(missing_ok=True)
    return _result(fault, seed, status, end_s, hang, stderr, problems, readable, reindexed, lost, orphans,
                   "{} steps lost (allowed 0 beyond the states the line names)",
                   "{} processes of the run left running")


def _bag_after(kind: str, runner: str, bag: Path, copy: Path, status: int | None, line: str | None,
               end_s: float | None, problems: list[str]) -> tuple[bool | None, bool, int | None]:
    """What a host-fault run left, checked (problems noted): its error line, and its bag (a copy, after
    ``reindex`` if it has to) holding exactly the world states the line names. Returns whether the bag
    is readable (None: not looked at), whether it needed reindex, and the steps lost."""
    readable, reindexed, lost = None, False, None
    if kind == "readonly" and status == HOST_FAULT_STATUS and line is not None and not (
            line.startswith("error: cannot write "
                            f"{bag / 'bag_0.mcap'}: Read-only file system (EROFS)")):
        problems.append("the line does not name the bag file and EROFS")
    if kind == "readonly" and status != HOST_FAULT_STATUS:
        problems.append(f"exit status {status}, expected {HOST_FAULT_STATUS}")
    if kind == "readonly" and end_s is not None and end_s > END_LIMIT_S:
        problems.append(f"ended {end_s:.1f} s after the fault")
    if kind in ("enospc", "readonly") and bag.is_dir():
        shutil.copytree(bag, copy)
        world = world_steps(copy)
        if world is None:
            from evoscen_record.reindex import reindex_bag

            with contextlib.suppress(Exception):
                reindex_bag(copy, keep_original=False)
                reindexed = True
            world = world_steps(copy)
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
    return readable, reindexed, lost


def _driver_kill(fault: tuple, seed: int, steps: int, rng: random.Random, work: Path, repo: Path) -> GraphResult:
    """A campaign whose driver is SIGKILLed mid-run (its process alone), then the same command: it
    must end the killed driver's Ray processes, and every run must be done exactly once."""
    import pyarrow.parquet as pq

    from evoscen_experiments.ray_leftovers import DRIVER_FILE, session_processes, zombie

    problems: list[str] = []
    camp = work / f"campaign-{seed}"
    camp.mkdir(parents=True, exist_ok=True)
    spec = camp / "spec.yaml"
    n_seeds = 4
    spec.write_text(f"name: faults\nsteps: {min(steps, 600)}\nseeds: {{first: {seed}, count: {n_seeds}}}\n"
                    "grid:\n  sut.model: [mobil, level0]\n", encoding="utf-8")
    out = camp / "out"
    cmd = [sys.executable, str(repo / "scripts" / "campaign.py"), str(spec), "--out", str(out), "--cpus", "2"]
    first = subprocess.Popen(cmd, cwd=repo, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
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
        again = subprocess.Popen(cmd, cwd=repo, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
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
    return _result(fault, seed, status, None, hang, stderr, problems, None, False, lost, orphans,
                   "{} runs missing after the resume", "{} Ray processes of the killed driver left running")


def _result(fault: tuple, seed: int, status: int | None, end_s: float | None, hang: bool, stderr: str,
            problems: list[str], readable: bool | None, reindexed: bool, lost: int | None, orphans: int,
            lost_problem: str, orphans_problem: str) -> GraphResult:
    """A host-fault run's result, its last problems noted: a hang, a traceback, a bag unreadable after
    reindex, ``lost`` and ``orphans`` (each counted into its ``*_problem`` text)."""
    traceback = "Traceback" in stderr
    if hang:
        problems.append("hang")
    if traceback:
        problems.append("traceback")
    if readable is False:
        problems.append("bag unreadable after reindex")
    if lost:
        problems.append(lost_problem.format(lost))
    if orphans:
        problems.append(orphans_problem.format(orphans))
    return GraphResult(" ".join(fault), seed, status, end_s, hang, traceback, readable, reindexed, lost,
                       orphans=orphans, problems=problems, stderr_tail=stderr_tail(stderr, problems))
