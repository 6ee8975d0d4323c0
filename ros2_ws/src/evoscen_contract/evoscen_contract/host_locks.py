"""Locks shared by every evoscen process of a host (standard library only).

* :func:`lock_dir`: the directory of the host's lock files — ``$EVOSCEN_DOMAIN_LOCK_DIR`` or
  ``<tmp>/evoscen-domains`` (mode 1777, lock files 0666, so the processes of different users of one
  host see each other's locks). The ROS_DOMAIN_ID reservations live there
  (:mod:`evoscen_bringup.domains`).
* :func:`participant_start_lock`: held while a node creates its DDS participant.

[choice] Participants are created one at a time on a host (docs/architecture.md §5). Fast DDS's
shared-memory transport gives every participant a host-wide port (``/dev/shm/fastrtps_port7000``,
``7001``, …, whatever the domain) and checks the health of the ports it opens; a graph's six node
processes creating their participants in the same instant on a loaded machine is the case in which
a node comes up deaf — its port rebuilt under it, ``Failed init_port fastrtps_port7001:
open_and_lock_file failed`` on stderr, its publishers never matched (seen about once in ten runs of
a test on a loaded 2-core machine; the same trigger is reported upstream: ros2/rmw_fastrtps#860,
eProsima/Fast-DDS#6117). Holding an exclusive ``flock`` around the participant's creation (about
30 ms) removes that concurrency for every evoscen node on the host, whichever graph it belongs to;
the kernel drops the lock when a process ends, however it ends. A lock not obtained within
:data:`START_LOCK_WAIT_S` (a stopped process holding it) is skipped: the node starts as before.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

START_LOCK_FILE = "participant-start.lock"
START_LOCK_WAIT_S = 30.0
"""How long a node waits for the participant-start lock before starting without it."""


def lock_dir() -> Path:
    """The directory of the host's lock files (created, mode 1777, if missing)."""
    env = os.environ.get("EVOSCEN_DOMAIN_LOCK_DIR")
    path = Path(env) if env else Path(tempfile.gettempdir()) / "evoscen-domains"
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(PermissionError):
            path.chmod(0o1777)  # the umask may have taken bits; shared by every user of the host
    return path


def open_lock_file(path: Path) -> int:
    """An fd of the lock file ``path`` (created 0666 so that other users can lock it too)."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    with contextlib.suppress(PermissionError):
        os.fchmod(fd, 0o666)
    return fd


@contextlib.contextmanager
def participant_start_lock(wait_s: float = START_LOCK_WAIT_S, poll_s: float = 0.005) -> Iterator[bool]:
    """Hold the host's participant-start lock for the ``with`` block; yields whether it was obtained
    (False after ``wait_s`` without it, or where no lock file can be made: the block runs anyway)."""
    try:
        fd = open_lock_file(lock_dir() / START_LOCK_FILE)
    except OSError:
        yield False
        return
    deadline = time.monotonic() + wait_s
    held = False
    try:
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                held = True
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    break
                time.sleep(poll_s)
        yield held
    finally:
        os.close(fd)  # closing the only fd of the open file description releases the lock
