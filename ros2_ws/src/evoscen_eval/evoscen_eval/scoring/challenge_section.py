"""The report's ``challenge`` section from the run's ``evoscen/challenge`` events (docs/challenges.md)."""

from __future__ import annotations

import math
from typing import Any

from evoscen_contract import contract as C


def challenge_of_events(events: list[dict]) -> dict[str, Any]:
    """The report's ``challenge`` section from the ``evoscen/challenge`` events (docs/challenges.md): every
    onset (step, time, the braking vehicle, its deceleration and duration, q/p) and the run's likelihood
    ratio p/q (``weight``; its log, exact) with the distance its SUT's leaders drove under the process; a run
    cut short before its summary event is weighted by its onsets alone and says so (``complete`` false)."""
    onsets = [{"step": int(e["step"]), "time_s": float(e["time_s"]), "vehicle": int(e["ids"][0]),
               "decel_mps2": -float(e["accel_mps2"]), "duration_s": float(e["duration_s"]),
               "multiplier": float(e["multiplier"])} for e in events if e.get("kind") == C.KIND_START]
    end = next((e for e in events if e.get("kind") == C.KIND_END), None)
    if end is not None:
        log_w, distance = float(end["log_weight"]), float(end["distance_m"])
    else:
        log_w, distance = -sum(math.log(o["multiplier"]) for o in onsets), None
    return {"onsets": onsets, "count": len(onsets), "log_weight": log_w, "weight": math.exp(log_w),
            "distance_m": distance, "complete": end is not None}
