"""What a run of the fault campaign gives and how it is checked (docs/recording.md, "Fault campaign";
``scripts/fault_campaign.py``): the result record, the limits, the world steps a run's bag holds, the
processes a run left. The campaign itself is :mod:`evoscen_experiments.faults`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from evoscen_contract.contract import TOPIC_WORLD

END_LIMIT_S = 10.0
"""A run must end within this long of the fault."""
HANG_S = 120.0
"""A run not ended this long after it started hangs."""
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
    stderr_tail: str = ""  # the launcher's last lines (and its log's, the simulation's), kept for runs with a problem
    orphans: int = 0  # processes of the run left running after it ended (driver-kill: after the resume)


def world_steps(bag: Path) -> list[int] | None:
    """The steps of the world states in ``bag``, sorted and distinct; None if it cannot be read."""
    from evoscen_record.bag_reader import open_bag_reader

    try:
        return sorted({t // DT_NS for topic, _type, t, _d in open_bag_reader(bag) if topic == TOPIC_WORLD})
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None


def stderr_tail(stderr: str, problems: list[str]) -> str:
    """The last 12 lines of a run's stderr, kept for a run with a problem (else empty)."""
    return "\n".join(stderr.strip().splitlines()[-12:]) if problems else ""


def kill_leftovers(pattern: str) -> int:
    """SIGKILL every process whose command line holds ``pattern`` (a run's output directory: its
    parameter files are under it); how many there were."""
    import contextlib
    import os
    import signal
    import subprocess

    pids = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout.split()
    for pid in pids:
        with contextlib.suppress(OSError):
            os.kill(int(pid), signal.SIGKILL)
    return len(pids)
