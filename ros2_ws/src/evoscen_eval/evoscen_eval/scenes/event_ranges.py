"""The time range around a run's collision or exposure, and the traffic window's shifts inside a range
(``export_scenario.py --event N --around T``, docs/export.md "A range around an event").

A shift (``evoscen/shift``) moves every vehicle back along the road between two states; its event carries
the time of the state it led to, the time this module names. A range *holds* a shift when it holds the
states on both sides of it. :func:`critical_events` lists the run's events as the report numbers them,
:func:`event_range` centres a range on one, on the side of every shift that holds the event, and
:func:`shift_warning` is the line an export of a range that holds a shift prints.
"""

from __future__ import annotations

from dataclasses import dataclass

from evoscen_contract import contract as C
from evoscen_sim.errors import InputError

AROUND_S = 5.0
"""Default seconds kept on either side of the event (``--around``): the critical-event clips' ``CLIP_S``
(SUMO SSM's default ``extratime``; docs/campaigns.md, "Critical events")."""
EPS_T = 1e-6
"""Times closer than this are the same time (s)."""


@dataclass(frozen=True)
class CriticalEvent:
    """A SUT collision or exposure of the run's report, its states as run times."""

    number: int
    """Its place in the list ``--event`` counts: the collisions first, then the exposures (from 1)."""
    kind: str
    """``collision`` or ``exposure``."""
    of_kind: int
    """Its number among its kind, as report.md shows it (``collision 2``, exposure table row 2)."""
    first_s: float
    last_s: float
    """Times of its first and last state (an exposure's dangerous states; a collision's one state)."""
    anchor_s: float
    """A collision's state, an exposure's worst state: the side of a shift it lies on is the range's."""

    @property
    def label(self) -> str:
        span = f"t = {self.first_s:.1f} s" if self.last_s - self.first_s < EPS_T else \
            f"t = {self.first_s:.1f} .. {self.last_s:.1f} s"
        return f"{self.kind} {self.of_kind} ({span})"


def critical_events(run) -> list[CriticalEvent]:
    """The SUT collisions of ``run`` (a :class:`~evoscen_eval.scoring.rundata.RunData`) by time, then its
    exposures in the report's order (``safety.collision_list``, ``safety.exposure_list``: what report.md
    numbers and the critical-event clips ``NNN-<kind>-<state>`` count)."""
    from evoscen_eval.scoring.report import report_of

    safety = report_of(run)["safety"]
    t = [float(x) for x in run.time_s]

    def at(state: int) -> float:
        return t[min(max(int(state), 0), len(t) - 1)]

    out = [CriticalEvent(n, "collision", n, at(c["state"]), at(c["state"]), at(c["state"]))
           for n, c in enumerate(safety["collision_list"], 1)]
    for n, x in enumerate(safety["exposure_list"], 1):
        # end_state is the first state after the exposure (or the run's end when it is open there)
        out.append(CriticalEvent(len(out) + 1, "exposure", n, at(x["start_state"]),
                                 at(max(int(x["end_state"]) - 1, int(x["start_state"]))), at(x["worst_state"])))
    return out


def pick_event(events: list[CriticalEvent], text: str) -> CriticalEvent:
    """The event ``--event`` names: ``N`` (collisions first, then exposures), ``collision:N`` or
    ``exposure:N``. Raises InputError naming the choices when there is no such event."""
    kind, _, num = text.strip().rpartition(":")
    try:
        n = int(num)
        if kind not in ("", "collision", "exposure") or n < 1:
            raise ValueError
    except ValueError:
        raise InputError(f"--event: {text!r}: expected a number N >= 1 (the report's collisions, then its "
                         "exposures), or collision:N or exposure:N") from None
    pool = [e for e in events if not kind or e.kind == kind]
    collisions = sum(e.kind == "collision" for e in events)
    counts = f"{collisions} collision(s) and {len(events) - collisions} exposure(s) of the SUT"
    if n > len(pool):
        what = f"{kind}s" if kind else "events"
        raise InputError(f"--event {text}: the run has {counts}" + (f": expected {what} 1 .. {len(pool)}" if pool else ""))
    return pool[n - 1]


def shifts_of(run) -> list[tuple[float, float]]:
    """The run's shifts: (time of the state each led to, metres every vehicle moved back), by time."""
    return sorted((float(e["time_s"]), float(e.get("shift_m", 0.0))) for e in run.events_named(C.EVENT_SHIFT))


def shifts_inside(t_lo: float, t_hi: float, shifts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The shifts a range ``[t_lo, t_hi]`` holds (the states before and after each inside it)."""
    return [s for s in shifts if t_lo + EPS_T < s[0] <= t_hi + EPS_T]


def event_range(event: CriticalEvent, around_s: float, bag_s: tuple[float, float], shifts: list[tuple[float, float]],
                dt_s: float) -> tuple[float, float, str | None]:
    """``(t_from, t_to, note)``: from ``around_s`` before the event's first state to ``around_s`` after
    its last, within the bag's ``bag_s`` = (first, last) state times. A range that would hold a shift
    keeps its length and moves to the side of the shift that holds the event's anchor, clipped there;
    ``note`` (else None) says so in one line."""
    lo, hi = max(event.first_s - around_s, bag_s[0]), min(event.last_s + around_s, bag_s[1])
    inside = shifts_inside(lo, hi, shifts)
    if not inside:
        return round(lo, 9), round(hi, 9), None
    side_lo = max([bag_s[0]] + [s for s, _ in shifts if s <= event.anchor_s + EPS_T])
    side_hi = min([bag_s[1]] + [s - dt_s for s, _ in shifts if s > event.anchor_s + EPS_T])
    width = hi - lo
    new_lo, new_hi = (side_hi - width, side_hi) if hi > side_hi + EPS_T else (side_lo, side_lo + width)
    new_lo, new_hi = round(max(new_lo, side_lo), 9), round(min(new_hi, side_hi), 9)
    when = ", ".join(f"{s:.1f}" for s, _ in inside)
    side = "before" if new_hi < inside[0][0] else "after"
    crosses = event.first_s < new_lo - EPS_T or event.last_s > new_hi + EPS_T
    cut = f"; the {event.kind} itself crosses the shift: the range holds its part {side} it" if crosses else ""
    note = (f"{event.label}: {lo:.1f} .. {hi:.1f} s would hold the shift at t = {when} s (every vehicle moved back "
            f"{inside[0][1]:g} m); exporting {new_lo:.1f} .. {new_hi:.1f} s, {side} it{cut}")
    return new_lo, new_hi, note


def shift_warning(t_lo: float, t_hi: float, shifts: list[tuple[float, float]]) -> str | None:
    """The warning of an export whose range ``[t_lo, t_hi]`` holds a shift (None when it holds none)."""
    inside = shifts_inside(t_lo, t_hi, shifts)
    if not inside:
        return None
    when = ", ".join(f"{s:.1f}" for s, _ in inside)
    moved = ", ".join(f"{m:g}" for _, m in inside)
    return (f"the range {t_lo:.1f} .. {t_hi:.1f} s holds the traffic window's shift at t = {when} s (every vehicle "
            f"moved back {moved} m): each vehicle's motion is cut there into pieces, the SUT's planning problem "
            "(CommonRoad) ends before it; --event N exports a range around an exposure or collision without one")
