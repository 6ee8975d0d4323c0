"""What a run of the fault campaign (``fault_campaign.py``) gives and how it is checked: the result
record, the limits, the paths, and the world steps a run's bag holds."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import _bootstrap  # noqa: F401  (makes the workspace packages importable)
from evoscen_contract.contract import TOPIC_WORLD

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = REPO / "scripts"
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


def world_steps(bag: Path) -> list[int] | None:
    from evoscen_record.bag_reader import open_bag_reader

    try:
        return sorted({t // DT_NS for topic, _type, t, _d in open_bag_reader(bag) if topic == TOPIC_WORLD})
    except Exception:  # noqa: BLE001 - unreadable, whatever the reason
        return None


def stderr_tail(stderr: str, problems: list[str]) -> str:
    """The last 12 lines of a run's stderr, kept for a run with a problem (else empty)."""
    return "\n".join(stderr.strip().splitlines()[-12:]) if problems else ""
