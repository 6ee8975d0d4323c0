#!/usr/bin/env python3
"""Checks of a compose graph's bag for docker/ci.sh (run with the project's .venv on the host).

    python docker/check_bag.py equal BAG_A BAG_B       the two bags' MCAP files are byte-identical
    python docker/check_bag.py aborted BAG CONTROLLER  readable; ends with an abort fault of CONTROLLER (or of one of its BV nodes, CONTROLLER_<part>)
    python docker/check_bag.py complete BAG STEPS      readable; STEPS SUT commands, a completed run_end

Prints one line per check; exit 0 when it holds, 1 when not, 2 on bad arguments.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import _bootstrap  # noqa: F401


def _messages(bag: Path) -> list[tuple[str, int, bytes]]:
    from evoscen_record.bag_reader import open_bag_reader

    return [(topic, t, data) for topic, _type, t, data in open_bag_reader(bag)]


def _events(bag: Path) -> list[dict]:
    from evoscen_eval.scoring.rundata import read_run

    return list(read_run(bag).events)


def main(argv: list[str]) -> int:
    if len(argv) != 3 or argv[0] not in ("equal", "aborted", "complete"):
        print(__doc__, file=sys.stderr)
        return 2
    what, a, b = argv
    if what == "equal":
        fa, fb = sorted(Path(a).glob("*.mcap")), sorted(Path(b).glob("*.mcap"))
        same = len(fa) == len(fb) == 1 and fa[0].read_bytes() == fb[0].read_bytes()
        print(f"check equal: {fa} vs {fb}: {'byte-identical' if same else 'DIFFERENT'}")
        return 0 if same else 1
    msgs = _messages(Path(a))
    events = _events(Path(a))
    ends = [e for e in events if e.get("name") == "evoscen/run_end"]
    if what == "aborted":
        faults = [e for e in events if e.get("name") == "evoscen/fault"]
        ok = bool(faults) and faults[-1].get("kind") == "abort" and str(faults[-1].get("controller")).startswith(b) \
            and len(ends) == 1 and ends[0].get("kind") == "aborted"
        print(f"check aborted: {len(msgs)} messages readable; last fault {json.dumps(faults[-1]) if faults else None}; "
              f"run_end {ends[0].get('kind') if ends else None}: {'ok' if ok else 'NOT as expected'}")
        return 0 if ok else 1
    n = sum(1 for topic, _t, _d in msgs if topic == "/evoscen/commands/sut")
    ok = n == int(b) and len(ends) == 1 and ends[0].get("kind") == "completed"
    print(f"check complete: {n} SUT commands (expected {b}); run_end {ends[0].get('kind') if ends else None}: "
          f"{'ok' if ok else 'NOT as expected'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
