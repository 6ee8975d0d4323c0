"""The Ray processes a campaign driver leaves behind when it is killed (SIGKILL: no clean-up).

While a driver with its own local Ray runs, ``OUT/.campaign-driver.json`` (:data:`DRIVER_FILE`)
holds its pid, start time and Ray session directory (:func:`evoscen_experiments.campaign.run_campaign`
writes it); the next campaign on the same ``OUT`` ends that session's processes
(:func:`end_leftovers`) unless the driver still runs. Linux only (``/proc``).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from pathlib import Path


DRIVER_FILE = ".campaign-driver.json"
"""In ``OUT``, while a driver with its own local Ray runs: its pid, start time and Ray session directory."""


def start_time(pid: int) -> str | None:
    """The process's start time (clock ticks since boot; None if there is no such process)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]


def session_processes(session_dir: str) -> list[tuple[int, str]]:
    """(pid, name) of the processes of a Ray session: its directory in their command line or open
    among their files (Ray's agents rename themselves, ``ray::DashboardAgent``, but keep their logs open)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit() or int(proc.name) == os.getpid():
            continue
        try:
            cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
            hit = session_dir in cmdline
            if not hit:
                for fd in (proc / "fd").iterdir():
                    with contextlib.suppress(OSError):
                        if os.readlink(fd).startswith(session_dir):
                            hit = True
                            break
        except OSError:
            continue  # gone meanwhile, or not ours to read
        if hit:
            found.append((int(proc.name), cmdline.split(" ")[0] or proc.name))
    return found


def end_leftovers(out_dir: Path, grace_s: float = 3.0) -> list[tuple[int, str]]:
    """End the Ray processes that a campaign driver killed before its end (SIGKILL: no clean-up)
    left running for ``out_dir``; returns them, (pid, name). Nothing if that driver still runs."""
    import signal

    path = out_dir / DRIVER_FILE
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
        pid, start, session = int(info["pid"]), info.get("start"), str(info["session_dir"])
    except (OSError, ValueError, KeyError, TypeError):
        return []
    if start_time(pid) is not None and start_time(pid) == start:
        return []  # that driver is still running
    found = session_processes(session) if session.startswith("/") and "session_" in session else []
    for p, _name in found:
        with contextlib.suppress(OSError):
            os.kill(p, signal.SIGTERM)
    end = time.monotonic() + grace_s
    while time.monotonic() < end and any(start_time(p) is not None and not zombie(p) for p, _ in found):
        time.sleep(0.1)
    for p, _name in found:
        if start_time(p) is not None and not zombie(p):
            with contextlib.suppress(OSError):
                os.kill(p, signal.SIGKILL)
    with contextlib.suppress(OSError):
        path.unlink()
    return found


def zombie(pid: int) -> bool:
    """Whether the process has ended but not been reaped yet (True also when it cannot be read)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True
