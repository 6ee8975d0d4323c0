"""ROS_DOMAIN_ID reservation (evoscen_bringup.domains, docs/architecture.md §5).

* With domains 1..99 held, an automatic reservation gets 100, the only free one; with all 100
  held it is a one-line error naming the range and the lock directory.
* A domain held by another process cannot be reserved explicitly (error naming the domain and
  its lock file); once that process has ended (the kernel drops its lock, even on SIGKILL),
  it can.
* A reservation ends with its ``with`` block.
* ``run_scenario.py --mode graph --domain-id N`` with N held: exit 2, one line, and the output
  directory is not created.
* A caller that reserved domain N and tells the launcher so (``EVOSCEN_DOMAIN_RESERVED=N``)
  gets N from the launcher's explicit reservation; the variable vouches for N only, not for
  another held domain.
* An unusable lock directory: one warning line, the run goes on with the asked domain.
"""

from __future__ import annotations

import contextlib
import random
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from evoscen_bringup.domains import AUTO_DOMAINS, RESERVED_ENV, reserve_domain, reserved_by_caller_env
from evoscen_sim.errors import InputError

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def lock_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "locks"
    monkeypatch.setenv("EVOSCEN_DOMAIN_LOCK_DIR", str(d))
    return d


def test_the_only_free_domain_is_taken(lock_dir: Path) -> None:
    with contextlib.ExitStack() as stack:
        held = [stack.enter_context(reserve_domain(d)) for d in range(1, 100)]
        assert held == list(range(1, 100))
        for seed in range(5):  # whatever the order of the draw
            with reserve_domain(None, random.Random(seed)) as d:
                assert d == 100
        with reserve_domain(100), pytest.raises(InputError) as exc, reserve_domain(None):
            pass
    msg = str(exc.value)
    assert "no free ROS_DOMAIN_ID in 1..100" in msg and str(lock_dir) in msg and "\n" not in msg
    assert AUTO_DOMAINS == range(1, 101)


def test_automatic_draws_differ_while_held(lock_dir: Path) -> None:
    rng = random.Random(3)
    with contextlib.ExitStack() as stack:
        got = [stack.enter_context(reserve_domain(None, rng)) for _ in range(100)]
    assert sorted(got) == list(range(1, 101))  # 100 reservations at once: every domain exactly once


def test_reservation_ends_with_its_block(lock_dir: Path) -> None:
    with reserve_domain(42) as d:
        assert d == 42
        with pytest.raises(InputError), reserve_domain(42):
            pass
    with reserve_domain(42) as d:
        assert d == 42


def test_domain_held_by_another_process(lock_dir: Path) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\n"
         "from evoscen_bringup.domains import reserve_domain\n"
         "with reserve_domain(57):\n    print('held', flush=True)\n    time.sleep(120)\n"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(InputError) as exc, reserve_domain(57):
            pass
        msg = str(exc.value)
        assert msg.startswith("--domain-id 57: another evoscen graph on this host runs on ROS_DOMAIN_ID 57")
        assert str(lock_dir / "domain-57.lock") in msg and "\n" not in msg
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with reserve_domain(57) as d:  # SIGKILL released it
        assert d == 57


def test_run_scenario_refuses_a_held_domain(lock_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    with reserve_domain(23):
        res = subprocess.run([sys.executable, "scripts/run_scenario.py", "--mode", "graph", "--domain-id", "23",
                              "--steps", "5", "--out", str(out), "--quiet"],
                             cwd=REPO, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --domain-id 23: another evoscen graph"), res.stderr
    assert "Traceback" not in res.stderr
    assert not out.exists()


_LAUNCHER = ("import sys\n"
             "from evoscen_bringup.domains import reserve_domain\n"
             "from evoscen_sim.errors import InputError\n"
             "try:\n"
             "    with reserve_domain(int(sys.argv[1])) as d:\n"
             "        print('reserved', d)\n"
             "except InputError as exc:\n"
             "    print('error:', exc)\n")


def test_a_domain_reserved_by_the_caller_is_trusted_for_that_domain_only(lock_dir: Path) -> None:
    import os

    assert reserved_by_caller_env(31) == {"ROS_DOMAIN_ID": "31", RESERVED_ENV: "31"}
    with reserve_domain(31), reserve_domain(32):  # this process (the caller) holds both
        env = {**os.environ, **reserved_by_caller_env(31)}
        told, other = (subprocess.run([sys.executable, "-c", _LAUNCHER, str(d)], env=env, capture_output=True,
                                      text=True, timeout=60, check=True).stdout.strip() for d in (31, 32))
        untold = subprocess.run([sys.executable, "-c", _LAUNCHER, "31"], capture_output=True, text=True,
                                timeout=60, check=True).stdout.strip()
    assert told == "reserved 31"
    assert other.startswith("error: --domain-id 32: another evoscen graph"), other
    assert untold.startswith("error: --domain-id 31: another evoscen graph"), untold


def test_unusable_lock_dir_warns_and_goes_on(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                            capsys: pytest.CaptureFixture) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    monkeypatch.setenv("EVOSCEN_DOMAIN_LOCK_DIR", str(blocker / "locks"))
    with reserve_domain(9) as d:
        assert d == 9
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("warning: ROS_DOMAIN_ID 9 not reserved: the lock directory is not usable")


# --------------------------------------------------------------------------- participants one at a time


def test_participant_start_lock_is_one_holder_at_a_time_and_released_after_the_block(lock_dir):
    """While another holder has the participant-start lock, a node waits for it and, past its wait,
    starts without it; the lock is free again once the block ends (evoscen_contract.host_locks)."""
    import fcntl
    import os
    import time

    from evoscen_contract.host_locks import START_LOCK_FILE, open_lock_file, participant_start_lock

    with participant_start_lock() as held:
        assert held and (lock_dir / START_LOCK_FILE).is_file()
        other = open_lock_file(lock_dir / START_LOCK_FILE)  # another open file description: another holder
        with pytest.raises(BlockingIOError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
    fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)  # released with the block
    try:
        start = time.monotonic()
        with participant_start_lock(wait_s=0.2) as held:
            waited = time.monotonic() - start
        assert held is False and 0.2 <= waited < 5.0  # waited its 0.2 s, then went on without it
    finally:
        os.close(other)
    with participant_start_lock(wait_s=0.2) as held:
        assert held


def test_make_node_creates_its_participant_under_the_lock(lock_dir):
    """``evoscen_contract.graph.make_node`` holds the lock while the participant is created: with the
    lock held elsewhere it waits (here the lock is freed after 0.5 s and the node is made after it)."""
    code = ("import fcntl, os, sys, threading, time\n"
            "from evoscen_contract import graph\n"
            "from evoscen_contract.host_locks import START_LOCK_FILE, lock_dir, open_lock_file\n"
            "fd = open_lock_file(lock_dir() / START_LOCK_FILE); fcntl.flock(fd, fcntl.LOCK_EX)\n"
            "threading.Timer(0.5, os.close, [fd]).start()\n"
            "graph.init([]); t0 = time.monotonic(); node = graph.make_node('probe')\n"
            "print(round(time.monotonic() - t0, 1) >= 0.4)\n"
            "node.destroy_node()\n")
    env = {**__import__("os").environ, "EVOSCEN_DOMAIN_LOCK_DIR": str(lock_dir), "ROS_DOMAIN_ID": "231",
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)
    assert res.returncode == 0 and res.stdout.strip() == "True", res.stdout + res.stderr
