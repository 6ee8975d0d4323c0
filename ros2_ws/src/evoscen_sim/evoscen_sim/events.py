"""What happened in a step, as the event dicts of ``/evoscen/events`` (no ROS here).

Each dict has ``name`` (``evoscen/<kind>``), optional ``level`` and ``message``, and typed
key/values (see ``evoscen_contract.topics.EVENT_KEY_TYPES``). Order within a step is fixed:
collisions, completed lane changes, aborted lane changes, re-entries, off-road.
"""

from __future__ import annotations


def step_events(world, result) -> list[dict]:  # noqa: ANN001
    """The events of one :meth:`evoscen_sim.world.World.step` result."""
    ids = world.ids
    common = {"step": result.step, "time_s": result.time_s}
    events: list[dict] = []
    for i, j in result.collisions:
        events.append({"name": "evoscen/collision", "message": f"vehicles {ids[i]} and {ids[j]} collide",
                       **common, "ids": [int(ids[i]), int(ids[j])]})
    for i, from_lane, to_lane, duration in result.lane_changes_completed:
        events.append({"name": "evoscen/lane_change", "message": f"vehicle {ids[i]}: lane {from_lane} -> {to_lane}",
                       **common, "ids": [int(ids[i])], "duration_s": duration,
                       "direction": 1 if to_lane > from_lane else -1, "from_lane": from_lane, "to_lane": to_lane,
                       "kind": "completed"})
    for i, from_lane, to_lane in result.lane_changes_aborted:
        events.append({"name": "evoscen/lane_change", "level": 1,
                       "message": f"vehicle {ids[i]}: lane change {from_lane} -> {to_lane} aborted, lane {to_lane} ended",
                       **common, "ids": [int(ids[i])], "direction": 1 if to_lane > from_lane else -1,
                       "from_lane": from_lane, "to_lane": to_lane, "kind": "aborted"})
    for i, lane, s in result.reentries:
        events.append({"name": "evoscen/reentry", "message": f"vehicle {ids[i]} re-entered lane {lane} at s = {s:.1f} m",
                       **common, "ids": [int(ids[i])], "to_lane": lane})
    for i in result.off_road:
        events.append({"name": "evoscen/off_road", "message": f"vehicle {ids[i]} left the road",
                       **common, "ids": [int(ids[i])]})
    return events


def has_events(result) -> bool:  # noqa: ANN001
    """Whether a step result produces any event."""
    return bool(result.collisions or result.lane_changes_completed or result.lane_changes_aborted
                or result.reentries or result.off_road)


def run_end_event(world, kind: str, message: str) -> dict:  # noqa: ANN001
    """The last event of every run: ``kind`` is completed, aborted or interrupted."""
    return {"name": "evoscen/run_end", "level": 0 if kind == "completed" else 2, "message": message,
            "step": world.step_index, "time_s": world.time_s, "steps": world.step_index, "kind": kind}


def fault_event(world, kind: str, controller: str, misses: int, message: str) -> dict:  # noqa: ANN001
    """A controller fault: ``kind`` deadline (command held) or abort."""
    return {"name": "evoscen/fault", "level": 1 if kind == "deadline" else 2, "message": message,
            "step": world.step_index, "time_s": world.time_s, "controller": controller, "misses": misses,
            "kind": kind}
